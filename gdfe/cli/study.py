"""``gdfe study NAME``: run one study of :mod:`studies` (writes a PNG and a JSON).

Progress on standard error (:mod:`gdfe.cli._progress`): the study's sweep and solves as a bar
on a terminal or a line every ~10 s elsewhere, and a line when it ends (name, ok/fail,
seconds); ``-q`` silences them. Standard output holds the numbers alone (text, or JSON).
"""

from __future__ import annotations

from pathlib import Path

from gdfe._validation import GdfeError
from gdfe.cli._common import emit, json_arg, noting, out_arg, output_folder, scheduler_arg, using_scheduler
from gdfe.cli._vocabulary import in_vocabulary

__all__ = ["register", "run"]


def register(sub):
    from studies import RESOLUTIONS, STUDIES

    p = sub.add_parser("study", help="run one study of a paper figure (writes a PNG and a JSON)",
                       description="Run one study: " + ", ".join(STUDIES) + ".")
    p.add_argument("name", choices=list(STUDIES), metavar="NAME", help="study: " + ", ".join(STUDIES))
    out_arg(p, help="output folder (default out/NAME)")
    p.add_argument("--resolution", choices=RESOLUTIONS, default="default")
    json_arg(p, "the numbers")
    scheduler_arg(p)
    p.set_defaults(func=run)


def run(args):
    import time

    import studies
    from gdfe.cli._progress import StudyProgress, progress_mode, study_line
    from studies._common import run_and_print

    try:
        module = studies.load(args.name)
    except ModuleNotFoundError as exc:  # a study needing an extra that is not installed
        raise GdfeError(f"study {args.name} ({studies.STUDIES[args.name]}) is not available: {exc}") from None
    out = args.out if args.out is not None else Path("out") / args.name
    folder = output_folder(out, args)
    t0 = time.perf_counter()
    progress = StudyProgress(progress_mode(args), f"study {args.name}")
    with noting(folder), using_scheduler(args.scheduler), folder, progress:
        if not hasattr(module, "NAME"):  # a study without the shared plumbing
            result = module.run(resolution=args.resolution, out=out)
            progress.write(study_line({"name": args.name, "status": "ok", "seconds": time.perf_counter() - t0}))
            emit(result, args.json, f"{args.name}: wrote {out}")
            return 0
        status = run_and_print(in_vocabulary(module), args.resolution, out, args.json)
        progress.write(study_line({"name": args.name, "status": "ok" if status == 0 else "fail",
                                   "seconds": time.perf_counter() - t0}))
        return status
