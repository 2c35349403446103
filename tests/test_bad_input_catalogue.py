"""The catalogue of bad inputs (``tests/bad_input_catalogue.py``): no traceback, no silent wrong result, no hang.

The default run tries every 8th case (a sample of every input class, a few dozen cases); the
test marked slow runs all of them, as ``python -m tests.bad_input_catalogue`` does for the table.
"""

import pytest

from bad_input_catalogue import OUTCOMES, catalogue, run, table


def _check(rows):
    bad = [r for r in rows if r["outcome"] in ("traceback", "silent", "hang", "obscure")]
    assert not bad, "\n".join(f"{r['outcome']}: {r['entry']} {r['class']}: {r['input']}: {r['message']}" for r in bad)
    assert all(r["outcome"] in OUTCOMES for r in rows)


def test_a_sample_of_the_catalogue():
    rows = run(every=8)
    assert len(rows) >= 80
    _check(rows)
    text = table(rows)
    assert text.splitlines()[-1].startswith("| **all** |") and "traceback" in text.splitlines()[0]


def test_the_catalogue_covers_every_input_class_and_both_entries():
    cases = catalogue()
    classes = {(c.klass, c.entry) for c in cases}
    for klass in ("design file", "folding-test CSV", "scan"):
        assert {(klass, "CLI"), (klass, "API")} <= classes, klass
    assert ("mask image or array", "API") in classes and ("CLI hinge arguments", "CLI") in classes
    assert len(cases) >= 700


@pytest.mark.slow
def test_the_whole_catalogue():
    _check(run())
