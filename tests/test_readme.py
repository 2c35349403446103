"""The README's and the docs' commands and examples run as written, and the docs build strictly."""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gdfe.cli import main

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = REPO / "docs"
#: Markdown files whose ```bash blocks are run command by command.
COMMAND_PAGES = [README, DOCS / "tutorial.md", DOCS / "install.md"]
#: Pages whose ```python blocks run in order in one namespace (the TOML block of designs.md is
#: the part.toml that designs.md loads).
PYTHON_PAGES = [README] + [DOCS / f"{name}.md" for name in ("paper", "models", "designs", "solver", "contact")]
#: The docs build, as README.md gives it after its install step.
MKDOCS_BUILD = "mkdocs build --strict"
#: Steps of a command line that set up the environment rather than use it.
SETUP = re.compile(r"^(python3? -m venv|\. \.venv/bin/activate|source \.venv/bin/activate|pip install)")


def blocks(lang, path=README):
    return re.findall(rf"```{lang}\n(.*?)```", path.read_text(), flags=re.S)


def runnable(line):
    """The part of a command line that a test runs: the set-up steps (venv, activation, pip install)
    removed; None for the test suite itself, the docs build (:func:`test_docs_build_strict`) and
    a line of set-up only."""
    steps = [step.strip() for step in line.split("&&")]
    steps = [step for step in steps if step and not SETUP.match(step)]
    command = " && ".join(steps)
    if not command or "pytest" in command or command.startswith(MKDOCS_BUILD):
        return None
    return command


def command_lines(path):
    lines = []
    for block in blocks("bash", path):
        for line in block.splitlines():
            line = line.strip()
            if line and not line.startswith("#") and runnable(line) is not None:
                lines.append(runnable(line))
    return lines


def test_readme_opens_with_install_and_test_commands():
    fences = re.findall(r"^```(\w*)\n(.*?)```", README.read_text(), flags=re.S | re.M)
    (lang1, first), (lang2, second) = fences[:2]
    assert lang1 == lang2 == "bash"
    assert first.count("\n") == second.count("\n") == 1, "each opening block is one command line"
    assert "pip install -e" in first and "gdfe hinge" in first
    assert "python -m pytest -q" in second
    assert len(README.read_text().splitlines()) <= 120


def test_readme_main_command(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    command = blocks("bash")[0].split("&&")[-1].strip()
    argv = shlex.split(command)
    assert argv[0] == "gdfe"
    assert main(argv[1:]) == 0
    out = capsys.readouterr().out
    assert "converged" in out
    assert (tmp_path / "out" / "hinge" / "hinge.pvd").is_file()
    # the figures quoted in the README are those the command prints
    quoted = blocks("text")[0]
    for line in ("GDFE fold angle  2.7317 rad", "Eq. 1            2.7372 rad"):
        assert line in quoted and line in out


def test_readme_links_resolve():
    for target in re.findall(r"\]\(([^)#]+)\)", README.read_text()):
        if "://" not in target:
            assert (REPO / target).exists(), f"README.md links to {target}, which does not exist"


def test_command_lines_are_found():
    readme = command_lines(README)
    assert readme[0].startswith("gdfe hinge --length 2.6")
    assert not any("pytest" in line or "pip install" in line for line in readme)
    assert any(line.startswith("gdfe design") for line in command_lines(DOCS / "tutorial.md"))
    assert any(MKDOCS_BUILD in block for block in blocks("bash"))


@pytest.mark.slow
@pytest.mark.parametrize("page", COMMAND_PAGES, ids=lambda p: p.name)
def test_page_commands_run(page, tmp_path):
    """Each command line of the page's ```bash blocks exits 0, run by bash in a fresh folder that
    holds docs/examples, so that outputs land in the temporary folder."""
    shutil.copytree(DOCS / "examples", tmp_path / "docs" / "examples")
    env = dict(os.environ, MPLBACKEND="Agg", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    for line in command_lines(page):
        done = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, f"{page.name}: `{line}` exited {done.returncode}:\n{done.stdout[-2000:]}" \
                                     f"\n{done.stderr[-2000:]}"


def test_python_examples(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "part.toml").write_text(blocks("toml", DOCS / "designs.md")[0])
    namespace = {}
    for page in PYTHON_PAGES:
        for code in blocks("python", page):
            exec(compile(code, str(page.relative_to(REPO)), "exec"), namespace)  # noqa: S102
    assert namespace["res"].converged


@pytest.mark.slow
def test_docs_build_strict(tmp_path):
    """`mkdocs build --strict` succeeds (every warning an error) and writes the gallery."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    pytest.importorskip("mkdocs_gen_files")
    env = dict(os.environ, MPLBACKEND="Agg", DISABLE_MKDOCS_2_WARNING="true", NO_MKDOCS_2_WARNING="1")
    site = tmp_path / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", *MKDOCS_BUILD.split()[1:], "--site-dir", str(site)],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    assert (site / "studies" / "index.html").is_file()
    assert (site / "api" / "simulation" / "index.html").is_file()
    from studies import STUDIES

    for name in STUDIES:
        assert (site / "studies" / name / "index.html").is_file(), name


def test_the_install_page_lists_every_extra_with_its_packages():
    """docs/install.md's table of extras says what pyproject.toml installs: every extra, and each
    package of it by name (the version bounds stay in pyproject.toml)."""
    import tomllib

    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    rows, cells = {}, {}
    for line in (DOCS / "install.md").read_text().splitlines():
        m = re.match(r"\|\s*`([\w-]+)`\s*\|([^|]*)\|", line)
        if m:
            cells[m.group(1)] = m.group(2)
            rows[m.group(1)] = {p.strip() for p in m.group(2).split(",") if p.strip()}
    assert set(rows) == set(extras)

    def names(packages):
        return {re.split(r"[<>=!~\[ ]", p, maxsplit=1)[0] for p in packages}

    for name, packages in extras.items():
        if name != "all":
            assert rows[name] == names(packages), (f"docs/install.md, extra {name}: lists {sorted(rows[name])}, "
                                                   f"installs {sorted(names(packages))}")
    # the table's "all": everything above but these
    left_out = re.search(r"everything above but (.*?) \(", cells["all"]).group(1)
    left_out = set(re.findall(r"`([\w-]+)`", left_out))
    assert names(extras["all"]) == set().union(*(names(p) for n, p in extras.items() if n not in left_out | {"all"}))


#: The solver page's names of the benchmark's designs.
_BENCH_DESIGNS = {"corrugation": "corrugation", "Figure 8 twist": "fig08-twist", "Figure 8 dome": "fig08-dome",
                  "Figure 8 saddle": "fig08-saddle"}


def test_the_solver_pages_table_is_the_benchmark_it_cites():
    """docs/solver.md's "Where it stands" table gives the numbers of the bench.json it links to: each
    row's iterations, seconds, start, peak, bound and bound iterations, so that a new benchmark cannot
    leave the page telling the old one's."""
    import json

    text = (DOCS / "solver.md").read_text()
    section = text[text.index("### Where it stands"):text.index("### The goals")]
    folder = re.search(r"\]\(bench/(\w+)/bench\.txt\)", section).group(1)
    sheets = {(r.get("design", "corrugation"), r["cells"]): r
              for r in json.loads((DOCS / "bench" / folder / "bench.json").read_text())["sheets"]}
    rows = [line for line in section.splitlines() if re.match(r"\| (corrugation|Figure 8 \w+) \|", line)]
    assert len(rows) == len(sheets) >= 4

    def num(s):
        return float(s.replace(" ", "").split()[0]) if s.strip() not in ("–", "-") else None

    for line in rows:
        design, cells, its, seconds, split, peak, bound, times = [c.strip() for c in line.strip("|").split("|")]
        r = sheets[(_BENCH_DESIGNS[design], int(cells.replace(" ", "")))]
        lb = r["lower_bound"]
        start, check = (num(x) for x in split.split("/"))
        assert int(its) == r["iterations"], line
        assert num(seconds) == pytest.approx(r["seconds"], rel=0.01, abs=0.005), line
        assert start is None or start == pytest.approx(r["start_s"], rel=0.02, abs=0.05), line
        assert check == pytest.approx(r["penetration_check_s"], rel=0.03, abs=0.005), line
        assert num(peak.replace("MiB", "")) == pytest.approx(r["peak_rss_mib"], abs=0.5), line
        unit = 1e-3 if bound.endswith("ms") else 1.0
        assert num(bound.replace("ms", "").replace("s", "")) * unit == pytest.approx(lb["bound_s"], rel=0.02), line
        assert int(times) == round(lb["bound_iterations"]), line
