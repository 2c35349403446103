"""What a diagnosis credits: the cause the data prove, or the alternatives they leave open.

A fit is not an explanation. A diagnosis names a model (its chosen model and the models the
data cannot tell from it, :mod:`gdfe.diagnosis.separate`); this module says which cause, if
any, it *credits*:

* a **measurement artefact** (a reading offset) is credited, as a measurement issue, when the
  verdict is ``measurement_issue``; an effect outside the catalogue of the same form stays open
  (the reading may be right);
* **one model** is credited only when the verdict is ``explained`` (within the noise, no
  structure left, every parameter in its physical range: :mod:`gdfe.diagnosis.verdict`) and it
  is named alone: no other model of the catalogue fits within the noise;
* with several models named and the verdict ``explained``, the effects that every one of them
  contains are credited (``effects``), the choice between the rest is left open;
* with the verdict ``partly_explained``, ``not_explained`` or ``structure_remains``, nothing is
  credited: what the chosen model leaves (residual structure, a misfit above the noise) or the
  parameters it needs (outside their physical range) say that the data hold something the
  catalogue lacks, and that something may also be what the chosen model imitates. The open
  alternatives then include :data:`OUTSIDE`, an effect outside the catalogue.

What is credited has a kind (:data:`gdfe.diagnosis.effects.KINDS`): a physical cause, a
measurement issue (a reading offset: the parts may have folded as modelled and been read
otherwise), or a factor of a column whose meaning was not declared (the fold changes with
the column; no physics is claimed).

The benchmark's strict rule (``studies/blind_diagnosis.py``) reads the same output: a data set
is wrong when a single physical cause is credited that is not the truth.
"""

from __future__ import annotations

import dataclasses

__all__ = ["Attribution", "attribute", "OUTSIDE"]

#: The name of the alternative that no catalogue model stands for.
OUTSIDE = "outside_catalogue"


def _terms(name):
    return [t for t in name.split("+") if t != "baseline"]


@dataclasses.dataclass
class Attribution:
    """The cause a diagnosis credits, and what it leaves open.

    Attributes
    ----------
    credited : str or None
        The model credited as the cause (its reported name), or None.
    kind : str or None
        Kind of the credit: ``"physics"``, ``"measurement"``, ``"factor"`` or ``"mixed"``.
    effects : list of str
        The effects credited: those of ``credited``, or the effects that every named model
        shares when the data cannot pick one of them.
    not_ruled_out : list of str
        Alternatives the data leave open: the other named models, and :data:`OUTSIDE` when the
        verdict says the catalogue falls short.
    text : str
        One sentence.
    """

    credited: str | None
    kind: str | None
    effects: list
    not_ruled_out: list
    text: str

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _kind(kinds):
    kinds = set(kinds)
    return None if not kinds else kinds.pop() if len(kinds) == 1 else "mixed"


def _words(kind):
    return {"physics": "a physical cause", "measurement": "a measurement issue, not physics",
            "factor": "a factor of an undeclared column, no physics claimed",
            "mixed": "a physical cause with a measurement issue or a column factor"}.get(kind, "")


def attribute(verdict, chosen, named, term_kinds, why_open=None):
    """The cause a diagnosis credits.

    Parameters
    ----------
    verdict : str
        One of :data:`gdfe.diagnosis.verdict.VERDICTS`.
    chosen : str
        The chosen model (``"baseline"`` when none).
    named : list of str
        The models the data cannot tell apart, ``chosen`` among them.
    term_kinds : dict of str -> list of (str, str)
        For each model of ``named`` (and ``chosen``), its terms (``"cure_depth"``,
        ``"factor[T_C]"``) with their kinds (``"physics"``, ``"measurement"``, ``"factor"``).
    why_open : str, optional
        Why the catalogue falls short (for :data:`OUTSIDE`), in words.

    Returns
    -------
    Attribution
    """
    named = list(dict.fromkeys(named or [chosen]))
    if verdict == "no_gap" or chosen == "baseline":
        if verdict in ("no_gap",):
            return Attribution(None, None, [], [], "nothing is credited: there is no gap to explain")
        return Attribution(None, None, [], [OUTSIDE],
                           "nothing is credited: no model of the catalogue removes a meaningful part of the gap"
                           + (f" ({why_open})" if why_open else ""))
    others = [m for m in named if m != chosen]
    if verdict == "measurement_issue":
        return Attribution(chosen, "measurement", _terms(chosen), others + [OUTSIDE],
                           f"credited: {chosen} ({_words('measurement')}); not ruled out: "
                           + ", ".join(others + ["an effect outside the catalogue of the same form, if the reading "
                                                 "is right"]))
    if verdict == "explained" and not others:
        kinds = [k for _, k in term_kinds.get(chosen, [])]
        kind = _kind(kinds)
        return Attribution(chosen, kind, _terms(chosen), [],
                           f"credited: {chosen} ({_words(kind)}); no other model of the catalogue fits within the "
                           f"noise")
    if verdict == "explained":
        sets = [dict(term_kinds.get(m, [])) for m in named]
        common = [t for t in sets[0] if all(t in s for s in sets[1:])]
        kind = _kind(sets[0][t] for t in common)
        if common:
            text = (f"credited: {', '.join(common)} ({_words(kind)}), which every model the data cannot tell "
                    f"apart contains; not ruled out: {', '.join(named)}")
        else:
            text = (f"no single cause is credited: the data cannot tell apart {', '.join(named)}, which share no "
                    f"effect")
        return Attribution(None, kind if common else None, common, named, text)
    open_ = others + [OUTSIDE]
    return Attribution(None, None, [], open_,
                       f"no cause is credited: {chosen} only describes part of the tests"
                       + (f" ({why_open})" if why_open else "")
                       + "; not ruled out: " + ", ".join(m if m != OUTSIDE else "an effect outside the catalogue"
                                                         for m in open_))
