"""``gdfe report``: every study run, and an HTML validation report of them (:mod:`studies.validation_report`).

Progress on standard error (:mod:`gdfe.cli._progress`): a line as each study ends (its name,
ok/fail/error/skipped, seconds), and between them a bar on a terminal or a line every ~10 s
elsewhere; ``-q`` silences both. Standard output holds the summary alone (text, or JSON).
"""

from __future__ import annotations


from gdfe.cli._common import emit, json_arg, noting, out_arg, output_folder, scheduler_arg, using_scheduler

__all__ = ["register", "run"]


def register(sub):
    from studies import RESOLUTIONS, STUDIES

    p = sub.add_parser("report", help="run every study and write an HTML validation report",
                       description="Run every study and write DIR/index.html with figures, paper-vs-ours "
                                   "numbers, regression tolerances and software versions.")
    out_arg(p, required=True)
    p.add_argument("--resolution", choices=RESOLUTIONS, default="default")
    p.add_argument("--only", nargs="+", choices=list(STUDIES), metavar="NAME", help="run only these studies")
    json_arg(p, "the report's summary")
    scheduler_arg(p)
    p.set_defaults(func=run)


def run(args):
    from gdfe.cli._progress import StudyProgress, progress_mode
    from studies import STUDIES
    from studies.validation_report import build_report

    names = args.only or list(STUDIES)
    folder = output_folder(args.out, args)
    mode = progress_mode(args)
    with noting(folder), using_scheduler(args.scheduler), folder, StudyProgress(mode, "report", total=len(names)):
        summary = build_report(args.out, resolution=args.resolution, names=names, progress=mode is not False)
    lines = [f"wrote {summary['index']}"]
    for s in summary["studies"]:
        lines.append(f"  {s['name']:<16} {s['status']:<8} {s.get('seconds', 0):6.1f} s  "
                     f"{s.get('passed', 0)}/{s.get('headlines', 0)} headlines pass")
    emit(summary, args.json, "\n".join(lines))
    return 0 if summary["ok"] else 1
