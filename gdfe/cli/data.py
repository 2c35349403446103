"""``gdfe data [NAME] [--out FILE]``: the data files that ship with the package.

``gdfe data`` lists them, ``gdfe data table1`` prints the path of one (so that
``gdfe diagnose "$(gdfe data table1)"`` works from any folder, installed or cloned), and
``--out FILE`` writes a copy to edit.
"""

from __future__ import annotations

from pathlib import Path

from gdfe._validation import GdfeError, check_choice
from gdfe.cli._common import emit, json_arg, new_file_path

__all__ = ["register", "run", "DATA_SETS"]

#: The shipped data sets: name -> (file in gdfe/data, what it holds).
DATA_SETS = {
    "table1": ("table1.csv", "the 18 folding tests of the paper's Table 1 (L_mm, d_mm, h_mm, alpha_rad)"),
}


def _path(name):
    from gdfe import paper

    return paper.TABLE1.parent / DATA_SETS[name][0]


def register(sub):
    p = sub.add_parser("data", help="the data files that ship with gdfe (Table 1)",
                       description="List the data files that ship with gdfe, print the path of one, or copy it: "
                                   "gdfe diagnose \"$(gdfe data table1)\" works from any folder.")
    p.add_argument("name", nargs="?", default=None, help=f"a data set: {', '.join(DATA_SETS)} (default: list them)")
    p.add_argument("--out", type=new_file_path, default=None, metavar="FILE",
                   help="write a copy of the data set to FILE (not replacing an existing file)")
    json_arg(p, "the data sets and their paths")
    p.set_defaults(func=run)


def run(args):
    from gdfe.io import write_text

    if args.name is None:
        if args.out is not None:
            raise GdfeError(f"--out: expected a data set name before it ({', '.join(DATA_SETS)})")
        listing = {name: {"path": str(_path(name)), "what": what} for name, (_, what) in DATA_SETS.items()}
        text = "\n".join(f"{name:8s} {entry['path']}\n         {entry['what']}" for name, entry in listing.items())
        emit({"data_sets": listing}, args.json, text, command="data")
        return 0
    name = check_choice("name", args.name, tuple(DATA_SETS))
    path = _path(name)
    out = {"name": name, "path": str(path)}
    text = str(path)
    if args.out is not None:
        target = Path(args.out)
        if target.exists():
            raise GdfeError(f"--out: {target} exists; expected a new file (remove it or choose another name)")
        if args.json not in (None, "-") and Path(args.json).absolute() == target.absolute():
            raise GdfeError(f"--out, --json: expected two files, got {target} for both (the JSON would replace the copy)")
        write_text(target, path.read_text())
        out["copied_to"] = str(target)
        text = f"wrote {target} (a copy of {path})"
    emit(out, args.json, text, command="data")
    return 0
