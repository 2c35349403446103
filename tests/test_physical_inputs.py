"""Inputs outside what the materials allow: lengths in micrometres, a contraction beyond the film's
free shrink, a coat too thin for any contraction ratio, a coarsening that loses a region, and a
calibration pinned at its eigenstrain's bound."""

import csv
import json
import re

import numpy as np
import pytest

import gdfe
from gdfe import paper
from gdfe._validation import R_MIN, GdfeError
from gdfe.cli import main
from gdfe.physical_ranges import MAX_CONTRACTION, RANGES

LAYOUT_FILM = '[film]\nd = 0.33\n[layout]\npixel = 0.1\nrows = [{rows}]\n'


def _said(caplog, text):
    """The warnings logged whose message contains ``text``."""
    return [r.getMessage() for r in caplog.records if r.levelname == "WARNING" and text in r.getMessage()]


# -- h and d: physical ranges, warnings in mm ---------------------------------------------------------
def test_h_and_d_have_ranges_that_hold_the_papers_films():
    for name in ("h", "d"):
        assert RANGES[name].unit == "mm" and RANGES[name].why
    with open(paper.TABLE1, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        assert RANGES["h"].contains(float(row["h_mm"])) and RANGES["d"].contains(float(row["d_mm"]))
    assert RANGES["h"].contains(paper.H) and RANGES["d"].contains(paper.FIG6_D)
    assert not RANGES["h"].contains(290.0) and not RANGES["d"].contains(330.0)


def test_hinge_warns_of_a_coat_thickness_in_micrometres(caplog):
    with caplog.at_level("WARNING"):
        gdfe.hinge(1.6, d=330.0)
    said = _said(caplog, "d = 330 mm")
    assert len(said) == 1
    lo, hi = RANGES["d"].lo, RANGES["d"].hi
    assert f"[{lo:g}, {hi:g}] mm" in said[0] and "micrometres" in said[0]


def test_design_file_in_micrometres_warns_of_h_and_d_once_each(tmp_path, caplog):
    path = tmp_path / "um.toml"
    path.write_text("[film]\nh = 290\nd = 330\n[hinge]\nlength = 1.6\n")
    with caplog.at_level("WARNING"):
        gdfe.load_design(path)
    assert len(_said(caplog, "h = 290 mm")) == 1 and len(_said(caplog, "d = 330 mm")) == 1
    assert "micrometres" in _said(caplog, "h = 290 mm")[0]


def test_a_layout_warns_once_not_once_per_cell(caplog):
    with caplog.at_level("WARNING"):
        gdfe.from_rows(["RRTTRR"] * 4, R=0.7, h=290.0, pixel=50.0)
    assert len(_said(caplog, "h = 290 mm")) == 1


@pytest.mark.parametrize("kwargs", [dict(R=0.2), dict(d=0.16)])
def test_a_contraction_beyond_the_films_free_shrink_warns(kwargs, caplog):
    with caplog.at_level("WARNING"):
        des = gdfe.hinge(1.6, **kwargs)
    c = 1.0 - float(des.meta["R"])
    assert c > MAX_CONTRACTION
    said = _said(caplog, "contract")
    assert len(said) == 1 and f"{c:.3g}" in said[0] and f"{MAX_CONTRACTION:g}" in said[0]


def test_films_within_their_ranges_do_not_warn(caplog):
    with caplog.at_level("WARNING"):
        gdfe.hinge(1.6, d=paper.FIG6_D)
        gdfe.hinge(1.6, R=0.7)
        gdfe.from_rows(["RRTTRR"] * 2, d=0.24, pixel=0.1)
    assert not [r for r in caplog.records if r.name == "gdfe.design"]


def test_cli_hinge_in_micrometres_says_so_on_standard_error(capsys):
    assert main(["hinge", "-L", "1.6", "--d", "330"]) == 0
    err = capsys.readouterr().err
    assert err.count("d = 330 mm") == 1 and "micrometres" in err


def test_cli_simulate_of_a_design_in_micrometres_says_so_once(tmp_path, capsys):
    path = tmp_path / "um.toml"
    path.write_text("[film]\nh = 290\nd = 330\n[hinge]\nlength = 1.6\n")
    main(["simulate", str(path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert err.count("h = 290 mm") == 1 and err.count("d = 330 mm") == 1


# -- a coat too thin: the threshold the message names passes -----------------------------------------
def test_the_thin_coat_threshold_is_one_that_passes():
    with pytest.raises(GdfeError, match=r"^d") as info:
        gdfe.hinge(1.6, d=0.11)
    need = float(re.search(r"needs d >= ([0-9.]+) mm", str(info.value)).group(1))
    des = gdfe.hinge(1.6, d=need)
    assert float(des.meta["R"]) >= R_MIN
    with pytest.raises(GdfeError, match=rf"^d.*needs d >= {need:g} mm"):
        gdfe.hinge(1.6, d=0.15)  # R = 0.0038 by Eq. 3: below R_MIN, named as d


# -- coarsening the FEM plate ------------------------------------------------------------------------
def test_coarsen_refuses_to_delete_a_one_pixel_hinge_or_pad_the_film():
    import reference_fem as rf

    des = gdfe.from_rows(["RRRRTRRRR"] * 5, d=0.33, pixel=0.1)
    with pytest.raises(GdfeError, match=r"^coarsen: .*got 2.*9 x 5.*only 1"):
        rf.plate_mesh(des, coarsen=2)
    even = gdfe.from_rows(["RRRTRRRR"] * 4, d=0.33, pixel=0.1)
    with pytest.raises(GdfeError, match=r"^coarsen: .*4 contract_top cells.*vanish"):
        rf.plate_mesh(even, coarsen=2)


def test_coarsen_keeps_a_coarsening_that_is_exact():
    import reference_fem as rf

    des = gdfe.from_rows(["RRTTRRRR"] * 4, d=0.33, pixel=0.1)
    plate = rf.plate_mesh(des, coarsen=2, refine=1)
    assert plate.grid.material.shape == (4, 2)
    assert (plate.grid.material == int(gdfe.Material.CONTRACT_TOP)).sum() == 2
    with pytest.raises(GdfeError, match=r"^coarsen: .*got 4.*factors that keep them: 2"):
        rf.plate_mesh(des, coarsen=4)


def test_cli_fem_simulate_refuses_a_coarsening_that_loses_the_hinge(tmp_path, capsys):
    path = tmp_path / "one_pixel.toml"
    path.write_text(LAYOUT_FILM.format(rows=", ".join(['"RRRRTRRRR"'] * 5)))
    assert main(["fem", "simulate", str(path), "--out", str(tmp_path / "o"), "--coarsen", "2"]) == 1
    assert "gdfe fem simulate: error: --coarsen 2: expected a factor that keeps" in capsys.readouterr().err


# -- the FEM calibration's eigenstrain ---------------------------------------------------------------
def _table1():
    t = gdfe.load_folding_tests(paper.TABLE1)
    return t.L, t.d, t.h, t.alpha


def test_a_calibration_in_micrometres_is_at_its_eigenstrains_bound_and_said(caplog):
    from reference_fem import fit_to_table

    L, d, h, alpha = _table1()
    with caplog.at_level("WARNING"):
        fit = fit_to_table(L, 1000 * d, 1000 * h, alpha, model="timoshenko")
    assert fit.at_bound and fit.eigenstrain_at_bound and not fit.E_ratio_at_bound
    assert fit.as_dict()["at_bound"] is True
    said = _said(caplog, "eigenstrain")
    assert len(said) == 1 and f"[{-MAX_CONTRACTION:g}, 0]" in said[0] and "micrometres" in said[0]


def test_the_calibration_of_table1_is_within_the_films_shrink(caplog):
    from reference_fem import fit_to_table

    with caplog.at_level("WARNING"):
        fit = fit_to_table(*_table1(), model="timoshenko")
    assert -MAX_CONTRACTION <= fit.eigenstrain < 0 and not fit.at_bound and not fit.eigenstrain_at_bound
    assert not _said(caplog, "eigenstrain")


def test_cli_fem_calibrate_in_micrometres_reports_the_bound(tmp_path, capsys):
    L, d, h, alpha = _table1()
    path = tmp_path / "um.csv"
    path.write_text("L_mm,d_mm,h_mm,alpha_rad\n" + "".join(
        f"{a:g},{1000 * b:g},{1000 * c:g},{e:g}\n" for a, b, c, e in zip(L, d, h, alpha)))
    assert main(["fem", "calibrate", "--table", str(path), "--model", "timoshenko", "--json"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["at_bound"] is True
    assert out.err.count("eigenstrain = ") == 1 and "micrometres" in out.err
    assert np.isfinite(json.loads(out.out)["eigenstrain"])
