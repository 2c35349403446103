"""The film parameters of a drawing's design: h, and R given or from d by Eq. 3 (the paper's defaults)."""

from __future__ import annotations

from gdfe._validation import GdfeError, check_positive, check_ratio, read_text


def film_ratio(h=None, R=None, d=None, K=None):
    """``(h, R, d)``: h default the paper's 0.29 mm; R as given, else Eq. 3 with ``d`` (default
    the paper's 0.33 mm) and ``K`` (default the paper's)."""
    from gdfe import paper
    from gdfe.calibration import Calibration

    h = paper.H if h is None else check_positive("h", h)
    if R is not None and d is not None:
        raise GdfeError(f"give the contraction ratio R or the passive thickness d, not both (got R={R:g}, d={d:g})")
    if R is not None:
        return h, float(check_ratio("R", R)), None
    d = paper.FIG6_D if d is None else check_positive("d", d)
    K = paper.K if K is None else check_positive("K", K)
    return h, float(Calibration(K=K, h=h).ratio(d)), float(d)


def load_toml(path):
    """A TOML file as a dict; a syntax error is reported with the file's name and the line."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib

    try:
        return tomllib.loads(read_text(path, "TOML file"))
    except tomllib.TOMLDecodeError as exc:
        raise GdfeError(f"{path.name}: not valid TOML: {exc}") from None
