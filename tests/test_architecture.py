"""The layers of the project, read from the source: no upward import, no import cycle.

Layers, each importing only itself and those below it (docs/ARCHITECTURE.md):

0. the library: ``gdfe`` and its subpackages, except the command line;
1. ``reference_fem`` (uses the library);
2. ``studies`` (use the library and the reference FEM);
3. the application: the command line ``gdfe.cli`` and ``gdfe.__main__``.

Every ``import`` counts, at module level or inside a function: a lazy import is still a
dependency. ``from PACKAGE import NAME`` depends on the submodule ``PACKAGE.NAME`` when there
is one, else on the package.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("gdfe", "reference_fem", "studies")


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules():
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports(name, path, known):
    """Project modules that module ``name`` (file ``path``) imports, with their line numbers."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_pkg = path.name == "__init__.py"
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
        else:
            continue
        for t in targets:
            # the longest known module the target names (``import a.b.c`` depends on a.b.c)
            parts = t.split(".")
            while parts and ".".join(parts) not in known:
                parts.pop()
            if parts:
                out.append((".".join(parts), node.lineno))
    return out


def layer(module):
    """0 library, 1 reference FEM, 2 studies, 3 application (the command line)."""
    if module == "gdfe.__main__" or module == "gdfe.cli" or module.startswith("gdfe.cli."):
        return 3
    return {"gdfe": 0, "reference_fem": 1, "studies": 2}[module.split(".")[0]]


@pytest.fixture(scope="module")
def graph():
    known = _modules()
    return {name: _imports(name, path, known) for name, path in known.items()}


def test_every_package_is_parsed(graph):
    assert {"gdfe", "gdfe.cli", "gdfe.solver", "reference_fem", "studies"} <= set(graph)
    assert len(graph) > 40


def test_no_module_imports_a_layer_above_its_own(graph):
    upward = [f"{mod} (layer {layer(mod)}) line {line} imports {dep} (layer {layer(dep)})"
              for mod, deps in graph.items() for dep, line in deps if layer(dep) > layer(mod)]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_the_library_imports_only_numpy_scipy_and_itself_at_module_level():
    """Optional packages are imported inside the functions that need them (``import gdfe`` stays light)."""
    allowed = {"numpy", "scipy", "gdfe", "tomli", "tomllib", "__future__"}
    import sys

    stdlib = set(sys.stdlib_module_names)
    bad = []
    for name, path in _modules().items():
        if layer(name) != 0:
            continue
        for node in ast.parse(path.read_text()).body:  # module level only
            if isinstance(node, ast.Import):
                roots = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                roots = [node.module.split(".")[0]]
            else:
                continue
            bad += [f"{name} line {node.lineno}: {r}" for r in roots if r not in allowed and r not in stdlib]
    assert not bad, "heavy module-level imports in the library:\n" + "\n".join(bad)


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w, _ in graph.get(v, ()):
            if w == v:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles(graph):
    cycles = _cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_the_checks_catch_what_they_look_for():
    """The two checks on a made-up graph: an upward import and a cycle are found."""
    fake = {"gdfe.design": [("studies.bench", 3)], "studies.bench": [("gdfe.design", 1)],
            "gdfe.mesh": []}
    assert _cycles(fake) == [["gdfe.design", "studies.bench"]]
    assert [d for m, ds in fake.items() for d, _ in ds if layer(d) > layer(m)] == ["studies.bench"]


def _public_classes(modules):
    """Public class name -> modules defining it at module level."""
    out = {}
    for name, path in modules.items():
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                out.setdefault(node.name, []).append(name)
    return out


def test_distinct_things_have_distinct_class_names():
    """Two public classes of one name (two ``Material``s, two ``Target``s) are two different things
    a reader takes for one."""
    twice = {c: m for c, m in _public_classes(_modules()).items() if len(m) > 1}
    assert not twice, "public classes defined more than once: " + "; ".join(f"{c} in {', '.join(m)}" for c, m in twice.items())


#: The paper's numbers that live in gdfe/paper.py alone: h, K, d of the Figure 6 hinges.
PAPER_NUMBERS = {0.29: "paper.H", 0.3706: "paper.K", 0.33: "paper.FIG6_D"}


def _paper_literals(source):
    """(line, value) of every float literal in code (not in strings) equal to one of the paper's numbers."""
    return [(n.lineno, n.value) for n in ast.walk(ast.parse(source))
            if isinstance(n, ast.Constant) and type(n.value) is float and n.value in PAPER_NUMBERS]


def test_the_papers_numbers_are_written_only_in_gdfe_paper():
    found = [f"{name} line {line}: {value} (use gdfe.{PAPER_NUMBERS[value]})"
             for name, path in _modules().items() if name != "gdfe.paper"
             for line, value in _paper_literals(path.read_text())]
    assert not found, "the paper's numbers written again:\n" + "\n".join(found)


def test_the_name_and_number_checks_catch_what_they_look_for(tmp_path):
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("class Material:\n    pass\n\n\nclass _Private:\n    pass\n")
    b.write_text("class Material:\n    pass\n\n\nclass _Private:\n    pass\n")
    assert _public_classes({"gdfe.a": a, "reference_fem.b": b}) == {"Material": ["gdfe.a", "reference_fem.b"]}
    assert _paper_literals('"""h = 0.29 mm"""\ndef f(h=0.29, d=0.33):\n    return 0.3706 * h\n') == [
        (2, 0.29), (2, 0.33), (3, 0.3706)]
