"""Shape diagnosis: regions, exact closest points, alignment, and localising a withheld hinge change."""

import json

import numpy as np
import pytest

import gdfe
from gdfe.cli import main
from gdfe.diagnosis import Surface, align_icp, design_regions, diagnose_shape, load_measured

# three hinges at uneven spacing, so that no symmetry of the strip maps one onto another
DESIGN = """
[film]
h = 0.29
R = 0.8
nz = 1

[layout]
pixel = 0.25
rows = [
  "RRRTTRRRRRTTRRTTRRRRRR",
  "RRRTTRRRRRTTRRTTRRRRRR",
]
"""


def _rotation(seed):
    q = np.random.default_rng(seed).standard_normal(4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                     [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                     [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])


@pytest.fixture(scope="module")
def design_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("shape") / "three_hinges.toml"
    p.write_text(DESIGN)
    return p


@pytest.fixture(scope="module")
def design(design_file):
    return gdfe.load_design(design_file)[0]


def _perturbed(design, region, R):
    regions = design_regions(design)
    Rc = design.R.copy()
    Rc[regions[region]] = R
    return gdfe.simulate(design.with_R(Rc)).points


def test_regions_of_a_layout(design):
    regions = design_regions(design)
    assert sorted(regions) == ["hinge_1", "hinge_2", "hinge_3", "panel_1", "panel_2", "panel_3", "panel_4"]
    assert [len(regions[f"panel_{k}"]) for k in (1, 2, 3, 4)] == [6, 10, 4, 12]
    # numbered along x
    xs = [design.mesh.cell_ij[regions[f"hinge_{k}"], 0].mean() for k in (1, 2, 3)]
    assert xs == sorted(xs)


def test_regions_of_a_hinge_are_its_own():
    assert sorted(design_regions(gdfe.hinge(2.0, R=0.9))) == ["hinge", "panel_a", "panel_b"]


def test_closest_points_are_exact(design):
    pts = gdfe.simulate(design).points
    surf = Surface(pts, design)
    rng = np.random.default_rng(1)
    X = pts[rng.integers(0, len(pts), 300)] + 0.02 * rng.standard_normal((300, 3))
    C, d, _ = surf.closest(X)
    np.testing.assert_allclose(np.linalg.norm(X - C, axis=1), d, atol=1e-12)
    # against a dense sampling of the bilinear faces: equal up to the sampling (0.003 mm) and
    # the four-triangle approximation of the faces
    u = np.linspace(0, 1, 81)
    uu, vv = (a.ravel() for a in np.meshgrid(u, u))
    w = np.stack([(1 - uu) * (1 - vv), uu * (1 - vv), uu * vv, (1 - uu) * vv], 1)
    from scipy.spatial import cKDTree

    dense = np.einsum("sk,fkc->fsc", w, surf.P).reshape(-1, 3)
    db, _ = cKDTree(dense).query(X)
    assert np.all(d <= db + 2e-3)
    assert np.all(db - d < 3e-3)


def test_icp_recovers_a_rigid_motion(design):
    pts = gdfe.simulate(design).points
    surf = Surface(pts, design)
    cloud = np.concatenate([pts, surf.P.mean(axis=1)])  # vertices and face centres lie on it
    Q0 = _rotation(7)
    moved = cloud @ Q0.T + np.array([3.0, -1.0, 2.0])
    Q, t, rms = align_icp(moved, surf)
    assert rms < 1e-6
    np.testing.assert_allclose(moved @ Q.T + t, cloud, atol=1e-6)


def test_unchanged_part_has_no_gap(design):
    pts = gdfe.simulate(design).points
    res = diagnose_shape(design, pts @ _rotation(3).T + 1.0)
    assert res.method == "correspondence"
    assert res.rms_before < 1e-9 and res.named == []


def test_correspondence_scan_localises_the_changed_hinge(design, tmp_path):
    """A VTU 'scan' of the design (same mesh) with hinge_2 contracting less, moved and noisy."""
    from gdfe.io import write_vtu

    rng = np.random.default_rng(4)
    pts = _perturbed(design, "hinge_2", 0.88)
    scan = pts @ _rotation(11).T + np.array([5.0, 1.0, -2.0]) + 0.003 * rng.standard_normal(pts.shape)
    path = write_vtu(tmp_path / "scan.vtu", scan, design)
    res = diagnose_shape(design, path)
    assert res.method == "correspondence"
    assert res.named == ["hinge_2"], res.text()
    assert res.corrected_R["hinge_2"] == pytest.approx(0.88, abs=0.005)
    assert res.rms_after < 0.3 * res.rms_before
    assert res.converged
    # invariance: another rigid motion of the scan gives the same deviation
    again = diagnose_shape(design, scan @ _rotation(12).T - 3.0, correct=False)
    assert again.rms_before == pytest.approx(res.rms_before, rel=1e-9)


def test_point_cloud_scan_localises_the_changed_hinge(design_file, design, tmp_path):
    """A CSV point cloud of the surface (no correspondences) with hinge_3 contracting more."""
    rng = np.random.default_rng(6)
    pts = _perturbed(design, "hinge_3", 0.72)
    surf = Surface(pts, design, per_edge=6)
    cloud = surf.samples[rng.choice(len(surf.samples), 700, replace=False)]
    cloud = cloud @ _rotation(21).T + np.array([10.0, -2.0, 3.0]) + 0.004 * rng.standard_normal(cloud.shape)
    path = tmp_path / "scan.csv"
    np.savetxt(path, cloud, delimiter=",", header="x,y,z", comments="")
    res = diagnose_shape(design_file, path)
    assert res.method == "icp"
    assert res.named == ["hinge_3"], res.text()
    assert res.corrected_R["hinge_3"] == pytest.approx(0.72, abs=0.01)
    assert res.rms_after < 0.3 * res.rms_before
    by = res.regions_by_name()
    assert by["hinge_3"]["single_fit_rms"] == min(by[f"hinge_{k}"]["single_fit_rms"] for k in (1, 2, 3))


def test_cli_diagnose_shape(design_file, design, tmp_path, capsys):
    pts = _perturbed(design, "hinge_1", 0.9)
    path = tmp_path / "scan.csv"
    np.savetxt(path, pts, delimiter=",")  # no header
    out = tmp_path / "shape.json"
    assert main(["diagnose-shape", str(design_file), str(path), "--json", str(out),
                 "--report", str(tmp_path / "rep"), "--align", "correspondence"]) == 0
    assert "the gap lies in hinge_1" in capsys.readouterr().out
    d = json.loads(out.read_text())
    assert d["named"] == ["hinge_1"] and len(d["element_deviation"]) == design.n_cells
    assert {r["name"] for r in d["regions"]} >= {"hinge_1", "panel_1"}
    assert (tmp_path / "rep" / "deviation.png").is_file()


def test_load_measured_errors(tmp_path):
    bad = tmp_path / "scan.xyz"
    bad.write_text("1 2 3\n")
    with pytest.raises(ValueError, match=r"path: expected a \.ply or \.vtu or \.obj or \.csv measured shape, "
                                         r"got 'scan\.xyz'"):
        load_measured(bad)
    p = tmp_path / "scan.csv"
    p.write_text("x,y,z\n0,0,0\n1,0,0\n0,one,0\n1,1,0\n")
    with pytest.raises(ValueError, match="scan.csv: line 4: expected three numbers"):
        load_measured(p)
    p.write_text("a,b,c\n0,0,0\n")
    with pytest.raises(ValueError, match="scan.csv: expected columns x, y, z, got a, b, c"):
        load_measured(p)
    with pytest.raises(FileNotFoundError, match="path: measured shape not found: .*none.csv"):
        load_measured(tmp_path / "none.csv")


def test_ply_is_read(design, tmp_path):
    import meshio

    pts = gdfe.simulate(design).points
    meshio.write(tmp_path / "scan.ply", meshio.Mesh(pts, []))
    got, cells = load_measured(tmp_path / "scan.ply")
    np.testing.assert_allclose(got, pts)
    assert cells is None


def test_auto_alignment_uses_correspondences_only_where_they_fit(design, tmp_path):
    pts = gdfe.simulate(design).points
    path = tmp_path / "same_count.csv"
    shuffled = pts[np.random.default_rng(0).permutation(len(pts))]
    np.savetxt(path, shuffled, delimiter=",")  # the right size, but not the design's vertices in order
    assert diagnose_shape(design, path, correct=False).method == "icp"
    assert diagnose_shape(design, path, correct=False, align="correspondence").method == "correspondence"


def test_exact_copy_of_the_vertices_has_no_floor(tmp_path):
    """The 1.6 mm hinge with two cell layers: a third of its vertices lie inside the film, h/2 from
    either face, which left ICP a 52 um floor. The copy now aligns by correspondences to round-off,
    and ICP on the surface vertices alone has no floor either."""
    from gdfe.io import surface_faces

    des = gdfe.hinge(1.6, d=0.33, nz=2)
    pts = gdfe.simulate(des).points
    moved = pts @ _rotation(5).T + np.array([1.0, 2.0, 3.0])
    path = tmp_path / "copy.csv"
    np.savetxt(path, moved, delimiter=",")
    res = diagnose_shape(des, path, correct=False)
    assert res.method == "correspondence" and res.rms_before < 1e-9 and res.matches
    on_surface = np.unique(surface_faces(des)[0])
    assert on_surface.size < len(pts)  # the interior (mid-plane) vertices are not on the surface
    _, _, rms = align_icp(moved[on_surface], Surface(pts, des))
    assert rms < 1e-9


# -- the scan must be the part -----------------------------------------------------------------------
def test_wrong_part_does_not_match(design, tmp_path):
    """The Figure 6 hinge's own VTU against the three-hinge strip: another part, no region named."""
    from gdfe.diagnosis.shape import MATCH_COVERAGE, NO_MATCH
    from gdfe.io import write_vtu

    other = gdfe.hinge(1.6, d=0.33)
    path = write_vtu(tmp_path / "hinge.vtu", gdfe.simulate(other).points, other)
    res = diagnose_shape(design, path)
    assert res.verdict == NO_MATCH and not res.matches
    assert res.regions == [] and res.named == [] and res.corrected_R == {}
    assert res.match["coverage"] < MATCH_COVERAGE and res.match["residual"] > 0
    assert res.n_simulations <= 10  # one nominal solve and at most 9 of the common-factor search
    text = res.text()
    assert text.startswith(NO_MATCH) and "RMS distance to the simulated surface" in text
    assert json.loads(json.dumps(res.as_dict()))["verdict"] == NO_MATCH


def test_identical_points_do_not_match(design):
    from gdfe.diagnosis.shape import NO_MATCH

    res = diagnose_shape(design, np.zeros((50, 3)))
    assert res.verdict == NO_MATCH and res.n_simulations == 0 and res.regions == []
    assert "1 distinct point" in res.match["reasons"][0]
    res = diagnose_shape(design, np.outer(np.linspace(0.0, 1.0, 30), [1.0, 2.0, 0.5]))  # collinear
    assert res.verdict == NO_MATCH and "a line at most" in res.match["reasons"][0]


def test_random_cloud_does_not_match(design):
    from gdfe.diagnosis.shape import MATCH_RESIDUAL, NO_MATCH

    cloud = np.random.default_rng(3).uniform(0.0, 10.0, (500, 3))
    res = diagnose_shape(design, cloud)
    assert res.verdict == NO_MATCH and res.named == []
    assert res.match["relative_residual"] > MATCH_RESIDUAL
    assert res.match["relative_residual"] == pytest.approx(res.match["residual"] / res.match["size"])


@pytest.mark.parametrize("scale", [10.0, 0.1])
def test_scale_error_does_not_match(design, scale):
    """The part's surface measured in cm (x0.1) or with a factor 10 too many."""
    from gdfe.diagnosis.shape import NO_MATCH

    pts = gdfe.simulate(design).points
    cloud = Surface(pts, design).samples * scale
    res = diagnose_shape(design, cloud, correct=False)
    assert res.verdict == NO_MATCH
    assert res.match["scale"] == pytest.approx(scale, rel=0.3) or res.match["factor"] != 1.0


def test_a_part_that_folded_less_everywhere_still_matches(design):
    """Every hinge at R = 0.9 instead of 0.8: far from the nominal shape, but one common factor of
    the contraction brings it back, so it is the part and its regions are reported."""
    R = np.where(design.R < 1.0, 0.9, 1.0)
    pts = gdfe.simulate(design.with_R(R)).points
    res = diagnose_shape(design, Surface(pts, design).samples, correct=False)
    assert res.matches and res.regions and res.verdict == "no gap localised"


def test_cli_scan_that_does_not_match(design_file, tmp_path, capsys):
    path = tmp_path / "cube.csv"
    np.savetxt(path, np.random.default_rng(1).uniform(0.0, 10.0, (200, 3)), delimiter=",")
    assert main(["diagnose-shape", str(design_file), str(path)]) == 4
    assert capsys.readouterr().out.startswith("the scan does not match the design")


def test_correspondence_needs_the_design_mesh(design):
    with pytest.raises(ValueError, match=rf"measured: expected the design's {design.mesh.n_points} vertices in its "
                                         r"order for correspondence alignment, got 10 points"):
        diagnose_shape(design, np.zeros((10, 3)) + np.arange(10)[:, None], align="correspondence")


@pytest.mark.parametrize("name, data", [("scan.vtu", b"<VTKFile>"), ("scan.ply", b"garbage\x00\x01"),
                                        ("scan.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                                                     b"end_header\n1 2\n")])
def test_corrupt_mesh_file_is_a_user_error_naming_it(tmp_path, name, data):
    """meshio ends with SystemExit or raises its own errors on such files; both become one GdfeError."""
    from gdfe._validation import GdfeError

    p = tmp_path / name
    p.write_bytes(data)
    fmt = name.rsplit(".", 1)[1].upper()
    with pytest.raises(GdfeError, match=rf"{name}: expected a readable {fmt} file, got one meshio cannot read"):
        load_measured(p)
