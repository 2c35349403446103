"""The README's commands and examples run as written."""

import re
import shlex
from pathlib import Path

from gdfe.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_opens_with_install_and_test_commands():
    first, second = blocks("bash")[:2]
    assert "pip install -e" in first and "gdfe hinge" in first
    assert "pytest" in second


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


def test_readme_python_examples(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "part.toml").write_text(blocks("toml")[0])
    namespace = {}
    for code in blocks("python"):
        exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102
    assert namespace["res"].converged
