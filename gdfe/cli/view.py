"""``gdfe view RESULT_DIR``: the simulated shape of a result folder as an interactive offline 3-D page.

The page is written by default beside the series (``RESULT_DIR/NAME.html``, ``NAME`` the
series' name), or where ``--html PATH`` says; the command says where it wrote it."""

from __future__ import annotations

from pathlib import Path

from gdfe._validation import GdfeError
from gdfe.cli._common import emit, file_path, json_arg, new_file_path

__all__ = ["register", "run"]


def register(sub):
    p = sub.add_parser("view", help="an interactive 3-D page of a simulated shape (offline HTML)",
                       description="Read the VTU series of a result folder (gdfe simulate/hinge --out DIR) and write "
                                   "a self-contained HTML page: the shape in 3-D with the contraction ramp as a "
                                   "slider. No network access is needed to open it.")
    p.add_argument("result", type=file_path, help="result folder (with a .pvd series), or the .pvd file")
    p.add_argument("--html", nargs="?", const=True, default=None, metavar="PATH", type=new_file_path,
                   help="where to write the page (default, and with --html alone: RESULT_DIR/NAME.html, "
                        "beside the .pvd series)")
    p.add_argument("--title", help="page title (default the series' name)")
    json_arg(p, "what was read and written")
    p.set_defaults(func=run)


def _series(path):
    from gdfe.io import MARKER, folder_state

    folder = path.parent if path.is_file() else path
    if folder_state(folder) == "incomplete":
        raise GdfeError(f"result: {folder} is incomplete ({MARKER}: the run that wrote it did not finish); "
                        "rerun it")
    if path.is_file():
        return path
    if not path.is_dir():
        raise GdfeError(f"result: expected a result folder or a .pvd file, got {path} (not found)")
    pvds = sorted(p for p in path.glob("*.pvd") if not p.name.startswith("."))
    if len(pvds) != 1:
        raise GdfeError(f"result: expected one .pvd series in {path}, got "
                        f"{', '.join(p.name for p in pvds) if pvds else 'none'}; give the .pvd file")
    return pvds[0]


def run(args):
    from gdfe.fabrication import read_series, write_viewer

    pvd = _series(args.result)
    data = read_series(pvd)
    if args.title:
        data.title = args.title
    summary = {"series": str(pvd), "frames": len(data.frames), "activation": data.activation.tolist(),
               "vertices": int(data.frames.shape[1]), "quads": len(data.quads)}
    text = (f"{pvd}: {summary['frames']} frames (activation {data.activation[0]:g} to {data.activation[-1]:g}), "
            f"{summary['quads']} surface faces")
    html = pvd.with_suffix(".html") if args.html in (None, True) else Path(args.html)
    summary["html"] = str(write_viewer(html, data))
    text += f"\n  wrote {html} (self-contained; open it in a browser)"
    emit(summary, args.json, text, command="view")
    return 0
