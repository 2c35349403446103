"""Forms of the shape diagnosis beyond one region's contraction (film anisotropy, coat offset),
the rule that credits one of them or none, and the model floor.

The scans here are GDFE's own shapes (moved rigidly, with noise): they test that each form's fit
recovers what made the scan, not that GDFE is right about parts (the blind benchmark,
``studies/blind_shape_diagnosis.py``, does that on the plate FEM's parts).
"""

import json
import math

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.cli._vocabulary import known_keys
from gdfe.diagnosis import design_regions, diagnose_shape
from gdfe.diagnosis.shape import NO_GAP, NO_GAP_BEYOND_FLOOR
from gdfe.diagnosis.shape_forms import (EFFECT_OVER_FLOOR, NAME_GAIN, RIVAL_TOL, FormFit, anisotropic_design,
                                        beyond, credit, mirrored, shifted_coat)
from gdfe.material import Material
from studies.shape_generators.designs import plate_design
from studies.shape_generators.parts import offset_material
from test_diagnosis_shape import DESIGN  # a module of tests/, which pytest puts on the path

THREE_HINGES = DESIGN  # three hinges at uneven spacing (the shape diagnosis's own test strip)


def _rotation(seed):
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=np.random.default_rng(seed)).as_matrix()


def _scan(points, seed, noise=0.003):
    rng = np.random.default_rng(seed)
    return points @ _rotation(seed).T + np.array([2.0, -1.0, 0.5]) + noise * rng.standard_normal(points.shape)


@pytest.fixture(scope="module")
def ell():
    """An L of two arms with a hinge across each (one bends about y, the other about x)."""
    return plate_design("ell").gdfe_design(0.8)


@pytest.fixture(scope="module")
def three_hinges(tmp_path_factory):
    p = tmp_path_factory.mktemp("forms") / "three_hinges.toml"
    p.write_text(THREE_HINGES)
    return p


def test_mirrored_design_folds_into_the_mirrored_shape(ell):
    """The energy is unchanged by a reflection: the design mirrored across x = y folds into the
    mirror image of its shape, to round-off."""
    a = gdfe.simulate(ell).points
    res = gdfe.simulate(mirrored(ell))
    assert res.converged
    assert gdfe.shape_distance(a, res.points[:, [1, 0, 2]])["rms"] < 1e-9


def test_anisotropy_of_one_is_the_design_and_keeps_the_mean(ell):
    a = gdfe.simulate(ell).points
    assert gdfe.shape_distance(a, gdfe.simulate(anisotropic_design(ell, 1.0, 1)).points)["rms"] < 1e-12
    des = anisotropic_design(ell, 0.8, 1)
    top, bottom = ell.face_contraction()
    t2, b2 = des.face_contraction()
    # x shrinks 2 / 1.8 times as much, y 0.8 times that: the mean of the two is the design's
    np.testing.assert_allclose((t2 + 0.8 * t2) / 2, top)
    np.testing.assert_allclose((b2 + 0.8 * b2) / 2, bottom)
    assert des.isotropy == 0.8


@pytest.mark.parametrize("face, axis, pixels", [("top", 0, 1), ("bottom", 1, -2), ("top", 1, 3)])
def test_shifted_coat_moves_the_mask_as_a_misprint_does(face, axis, pixels):
    """The diagnosis's own shift of a face's coat gives the material grid of the benchmark's
    misprinted part (written apart, in studies/shape_generators/parts.py)."""
    for name in ("strip", "ell"):
        pd = plate_design(name)
        des = pd.gdfe_design(0.9)
        moved = shifted_coat(des, face, axis, pixels)
        expected = pd.gdfe_design(0.9, material=offset_material(pd, face, axis, pixels))
        assert np.array_equal(moved.material, expected.material), (name, face, axis, pixels)
        # cells that start to shrink keep a contraction ratio
        assert np.all(moved.R[moved.material != Material.RIGID] < 1.0)
    assert shifted_coat(des, "top", 0, 0) is None


@pytest.mark.parametrize("weak_axis", [0, 1])
def test_anisotropy_form_recovers_a_gdfe_made_anisotropy(ell, weak_axis):
    made = gdfe.simulate(anisotropic_design(ell, 0.8, weak_axis)).points
    pts = made[:, [1, 0, 2]] if weak_axis == 0 else made
    res = diagnose_shape(ell, _scan(pts, 3 + weak_axis))
    assert res.outcome == "credited", res.text()
    assert res.credited["kind"] == "anisotropy" and res.credited["params"]["weak_axis"] == "xy"[weak_axis]
    assert res.credited["params"]["ratio"] == pytest.approx(0.8, abs=0.02)
    assert res.named == [] and "anisotropic" in res.verdict
    assert res.rms_after < 0.3 * res.rms_before
    kinds = {f["kind"] for f in res.forms}
    assert kinds == {"region", "anisotropy", "offset"}


@pytest.mark.parametrize("face, axis, pixels", [("bottom", 1, -1), ("top", 0, 2)])
def test_offset_form_recovers_a_gdfe_made_coat_offset(face, axis, pixels):
    ell = plate_design("ell").gdfe_design(0.9)  # a part that folds less: a 2-pixel offset still matches it
    pts = gdfe.simulate(shifted_coat(ell, face, axis, pixels)).points
    res = diagnose_shape(ell, _scan(pts, 7))
    assert res.outcome == "credited", res.text()
    p = res.credited["params"]
    assert (res.credited["kind"], p["face"], p["axis"], p["pixels"]) == ("offset", face, "xy"[axis], pixels)
    assert res.rms_after < 0.3 * res.rms_before
    assert f"{pixels:+d} pixels off its mask along {'xy'[axis]}" in res.verdict


def _form(name, rms, kind="region"):
    return FormFit(name, kind, {}, rms)


def test_rival_forms_that_fit_alike_are_not_credited():
    forms = [_form("contraction of hinge_a", 0.010), _form("film anisotropy (weaker along y)", 0.0102, "anisotropy"),
             _form("top coat offset along x", 0.030, "offset")]
    c = credit(forms, rms0=0.05)
    assert c.outcome == "cannot_tell" and c.credited is None
    assert c.not_ruled_out == ["contraction of hinge_a", "film anisotropy (weaker along y)"]
    # the same best form with its rival clearly behind is credited
    forms[1] = _form("film anisotropy (weaker along y)", 0.025, "anisotropy")
    c = credit(forms, rms0=0.05)
    assert c.outcome == "credited" and c.credited.name == "contraction of hinge_a" and c.not_ruled_out == []
    # the rule's edge: a rival within RIVAL_TOL of the best's RMS deviation is not ruled out
    edge = (1 + RIVAL_TOL) * 0.010
    assert credit([forms[0], _form("b", edge * (1 - 1e-9))], 0.05).outcome == "cannot_tell"
    assert credit([forms[0], _form("b", edge * (1 + 1e-9))], 0.05).outcome == "credited"
    # with a floor, a gap below it credits nothing however well a form fits
    assert credit(forms, rms0=0.05, floor=0.06).outcome == "within_floor"
    # a best form that removes less than NAME_GAIN of the part beyond the floor credits nothing
    c = credit([_form("a", 0.048)], rms0=0.05, floor=0.03)
    assert c.outcome == "no_form" and c.gain == pytest.approx(1 - beyond(0.048, 0.03) / 0.04)
    # beyond the floor, but by less than the floor itself: a form that fits below the floor may have
    # absorbed the models' disagreement, so nothing is credited; just past the edge it is
    floor = 0.03
    edge = math.sqrt(floor**2 + (EFFECT_OVER_FLOOR * floor) ** 2)
    c = credit([_form("a", 0.02)], rms0=edge * (1 - 1e-9), floor=floor)
    assert c.outcome == "within_disagreement" and c.credited is None and c.gain == 1.0
    assert credit([_form("a", 0.02)], rms0=edge * (1 + 1e-9), floor=floor).outcome == "credited"


def test_the_floor_suppresses_a_gap_below_it_and_lets_one_above_it_through(three_hinges):
    des = gdfe.load_design(three_hinges)[0]
    R = des.R.copy()
    R[design_regions(des)["hinge_2"]] = 0.84
    scan = _scan(gdfe.simulate(des.with_R(R)).points, 5)
    free = diagnose_shape(des, scan)
    assert free.named == ["hinge_2"] and free.floor is None
    rms0 = free.rms_before
    above = diagnose_shape(des, scan, floor=1.5 * rms0)
    assert above.outcome == "within_floor" and above.named == [] and above.verdict == NO_GAP_BEYOND_FLOOR
    assert above.level == pytest.approx(np.hypot(1.5 * rms0, above.noise))
    below = diagnose_shape(des, scan, floor=0.5 * rms0)
    assert below.named == ["hinge_2"], below.text()
    assert below.gain >= NAME_GAIN
    assert below.gain == pytest.approx(1 - beyond(below.rms_after, 0.5 * rms0) / beyond(rms0, 0.5 * rms0))


def test_a_scan_of_the_design_has_no_gap_with_or_without_a_floor(three_hinges):
    """The part as designed with the scanner's noise only: within the noise, nothing credited."""
    des = gdfe.load_design(three_hinges)[0]
    null = _scan(gdfe.simulate(des).points, 6)
    assert diagnose_shape(des, null).verdict == NO_GAP
    assert diagnose_shape(des, null, floor=0.0).verdict == NO_GAP_BEYOND_FLOOR


@pytest.mark.parametrize("bad", [-0.01, float("nan"), float("inf"), "thin"])
def test_bad_floor_values_raise(ell, bad):
    with pytest.raises(ValueError, match=r"floor: expected a finite RMS distance >= 0 in mm"):
        diagnose_shape(ell, np.random.default_rng(0).uniform(0, 1, (20, 3)), floor=bad)


def test_cli_floor_and_its_json(three_hinges, tmp_path, capsys):
    des = gdfe.load_design(three_hinges)[0]
    path = tmp_path / "scan.csv"
    np.savetxt(path, _scan(gdfe.simulate(des).points, 2), delimiter=",")
    assert main(["diagnose-shape", str(three_hinges), str(path), "--floor", "-1"]) == 1
    assert "floor: expected a finite RMS distance >= 0 in mm" in capsys.readouterr().err
    out = tmp_path / "shape.json"
    assert main(["diagnose-shape", str(three_hinges), str(path), "--floor", "0.05", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["verdict"] == NO_GAP_BEYOND_FLOOR and d["floor_mm"] == 0.05 and d["outcome"] == "within_floor"
    assert {f["kind"] for f in d["forms"]} == {"region", "anisotropy", "offset"}
    unknown = set(d) - known_keys("diagnose-shape")
    assert not unknown, f"gdfe diagnose-shape: keys neither in the vocabulary nor its own: {sorted(unknown)}"


@pytest.mark.parametrize("align, sigma, expected", [("correspondence", 0.005, 0.005 * np.sqrt(3)),
                                                    ("icp", 0.005, 0.005)])
def test_scan_noise_is_the_noise_of_a_scan_of_the_design(ell, align, sigma, expected):
    """A scan of the design's own shape with Gaussian noise: the noise the diagnosis estimates is
    that of a vertex's distance (correspondences, three coordinates) or of a distance to the
    surface (ICP, the normal component), within 15 %; without noise it is nearly nothing."""
    from gdfe.diagnosis import Surface

    pts = gdfe.simulate(ell).points
    cloud = pts if align == "correspondence" else Surface(pts, ell, per_edge=4).samples
    noisy = cloud + sigma * np.random.default_rng(11).standard_normal(cloud.shape)
    res = diagnose_shape(ell, noisy, align=align, correct=False)
    assert res.noise == pytest.approx(expected, rel=0.15)
    assert diagnose_shape(ell, cloud, align=align, correct=False).noise < 0.05 * expected
