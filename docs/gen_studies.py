"""Write the studies gallery at build time (mkdocs-gen-files): one page per registered study.

The registry is ``studies.STUDIES``; each page is the study module's docstring (what paper figure
it reproduces), the commands that run it and the figures it stored under ``docs/`` (found by the
PNG names its docstring says it writes). Nothing is executed but the imports.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import mkdocs_gen_files

from studies import STUDIES

DOCS = Path(__file__).resolve().parent

#: Pictures in docs/ that belong to a study without being one of its outputs.
RELATED = {"fig06": [("hinge.png", "The L = 2.6 mm hinge of Figure 6 folded by `gdfe hinge` (README)")]}

_ROLE = re.compile(r":(?:func|mod|class|data|attr|meth|obj):`~?([^`]+)`")


def markdown(text):
    """The reStructuredText of a docstring as Markdown: roles and double back-quotes to code."""
    text = _ROLE.sub(r"`\1`", text)
    return text.replace("``", "`")


def stored_figures(doc):
    """Paths (relative to docs/) of the PNGs the docstring names that a run stored under docs/."""
    names = dict.fromkeys(re.findall(r"``([\w.-]+\.png)``", doc))
    found = []
    for name in names:
        found += sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob(name))
    return found


#: Where the figures of every study's coarse run are kept (``gdfe report --resolution coarse --out``,
#: the PNGs of each study's folder copied into ``docs/gallery/NAME/``).
GALLERY = "gallery"


def coarse_figures(name):
    """Paths (relative to docs/) of the figures of the study's coarse run kept in the gallery."""
    return sorted(p.relative_to(DOCS).as_posix() for p in (DOCS / GALLERY / name).glob("*.png"))


def page(name, module, doc, figures):
    title, _, body = doc.strip().partition("\n")
    lines = [f"# {name}", "", f"**{markdown(title.strip())}**", "", markdown(body.strip()), "",
             "## Run it", "",
             "A quick look at coarse resolution, then the default resolution, then the same as a script:", "",
             "```bash",
             f"gdfe study {name} --resolution coarse --out out/{name}",
             f"gdfe study {name} --out out/{name}",
             f"python -m {module} --out out/{name}",
             "```", "",
             "Add `--scheduler tcp://HOST:8786` to run the independent simulations on a Dask cluster "
             "(`pip install -e \".[cluster]\"`).", ""]
    lines += ["## Stored figures", ""]
    if figures:
        for path, caption in figures:
            lines += [f"![{caption}](../{path})", "", f"*{caption}*", ""]
            stem = path[:-len(".png")]
            if (DOCS / f"{stem}.json").is_file():
                lines += [f"Its numbers: [`{stem}.json`](../{stem}.json).", ""]
    else:
        lines += ["None stored in the repository: run the study to make them.", ""]
    return "\n".join(lines)


def card(name, doc, figures):
    """A gallery card: the first stored figure as a thumbnail, the study's title under it."""
    title = markdown(doc.strip().splitlines()[0].rstrip("."))
    thumb = f"[![{name}](../{figures[0][0]}){{ loading=lazy style=\"max-height:200px\" }}]({name}.md)"
    return f"-   **[{name}]({name}.md)**\n\n    {thumb}\n\n    {title}\n"


def row(name, doc):
    """A table row for a study without a stored figure."""
    title = markdown(doc.strip().splitlines()[0].rstrip("."))
    return f"| [{name}]({name}.md) | {title} | `gdfe study {name}` |"


def main():
    cards, rows = [], []
    for name, module in STUDIES.items():
        doc = importlib.import_module(module).__doc__ or name
        figures = [(path, f"{Path(path).name}: the study at coarse resolution (`gdfe report --resolution coarse`)")
                   for path in coarse_figures(name)]
        figures += [(path, f"{Path(path).name}, stored under docs/{Path(path).parent.as_posix()}/")
                    for path in stored_figures(doc) if not path.startswith(f"{GALLERY}/")]
        figures += RELATED.get(name, [])
        with mkdocs_gen_files.open(f"studies/{name}.md", "w") as f:
            f.write(page(name, module, doc, figures))
        if figures:
            cards.append(card(name, doc, figures))
        else:
            rows.append(row(name, doc))
    index = ["# Studies", "",
             "One script per paper figure, comparison and diagnosis report: `gdfe study NAME` runs "
             "one, `gdfe report --out DIR` runs them all into an HTML report. The pictures are those "
             "of every study's coarse run (`gdfe report --resolution coarse`, kept in `docs/gallery/`) "
             "and those stored from their default runs; this site runs none of them ([how these "
             "pages are made](../about.md)).",
             "", "## Figures", "",
             '<div class="grid cards" markdown>', ""] + cards + [
             "</div>", ""]
    if rows:
        index += ["## Run them to see their figures", "",
                  "| study | reproduces | run it |", "|---|---|---|"] + rows + [""]
    with mkdocs_gen_files.open("studies/index.md", "w") as f:
        f.write("\n".join(index))


main()
