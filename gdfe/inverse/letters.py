"""Letters as chains of couples: the single-stroke glyphs of the paper's Figure 9 ("Concordia").

Each glyph is one stroke of at most three couples ``(L, r)`` (arcs of length ``L`` [mm] and
signed radius ``r`` [mm], ``r = 0`` straight, ``r > 0`` anticlockwise; paper Fig. 9), with
the heading of its tangent and its first point in the letter's own frame. A strip folds
into one stroke, so the dot of the ``i`` is left out.

Sizes: the capital C has radius 3 mm; the x-height is about 4 mm; the ascender of the d
is 8 mm. The paper prints no couples; these are drawn to the shapes of its figure.

All lengths in millimetres, angles in radians.
"""

from __future__ import annotations

import dataclasses
import math

from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.inverse.couples import as_couples

__all__ = ["Glyph", "LETTERS", "glyph", "text_glyphs"]


@dataclasses.dataclass(frozen=True)
class Glyph:
    """One stroke of a letter.

    Attributes
    ----------
    char : str
        The letter.
    couples : tuple of (L, r)
        Arc lengths and signed radii [mm] of the stroke's couples.
    heading : float [rad]
        Direction of the tangent at the stroke's start.
    start : (2,) tuple of float [mm]
        The stroke's first point in the letter's frame.
    """

    char: str
    couples: tuple
    heading: float
    start: tuple

    def as_couples(self):
        """The stroke as a list of :class:`gdfe.inverse.Couple`."""
        return as_couples(self.couples)


def _g(char, couples, heading, start):
    return Glyph(char, tuple(tuple(c) for c in couples), float(heading), tuple(float(x) for x in start))


_S2 = math.sqrt(2.0)

#: The glyphs of Figure 9, by letter (case matters: ``C`` and ``c`` differ in size).
LETTERS = {g.char: g for g in (
    _g("C", [(3.0 * 1.5 * math.pi, 3.0)], 0.75 * math.pi, (3.0 / _S2, 3.0 / _S2)),
    _g("o", [(2.0 * 2 * math.pi, 2.0)], 0.5 * math.pi, (2.0, 0.0)),
    _g("n", [(3.0, 0.0), (1.25 * math.pi, -1.25), (3.0, 0.0)], 0.5 * math.pi, (0.0, -2.0)),
    _g("c", [(2.0 * 1.5 * math.pi, 2.0)], 0.75 * math.pi, (2.0 / _S2, 2.0 / _S2)),
    _g("r", [(2.5, 0.0), (1.5 * 0.5 * math.pi, -1.5)], 0.5 * math.pi, (0.0, -2.0)),
    _g("d", [(2.0, 0.0), (2.0 * 2 * math.pi, 2.0), (4.0, 0.0)], 0.5 * math.pi, (2.0, -2.0)),
    _g("i", [(4.0, 0.0)], 0.5 * math.pi, (0.0, -2.0)),
    _g("a", [(2.0, 0.0), (2.0 * 2 * math.pi, -2.0), (2.0, 0.0)], -0.5 * math.pi, (2.0, 2.0)),
)}


def glyph(char):
    """The :class:`Glyph` of one letter.

    Raises
    ------
    GdfeError
        For a letter without a glyph (the message lists those there are).
    """
    if not isinstance(char, str) or len(char) != 1:
        raise GdfeTypeError(f"letter: expected one character, got {char!r}")
    try:
        return LETTERS[char]
    except KeyError:
        raise GdfeError(f"letter: expected one of {' '.join(sorted(LETTERS))} (the glyphs of Figure 9), "
                        f"got {char!r}") from None


def text_glyphs(text):
    """The glyphs of the letters of ``text``, in order (spaces skipped).

    Raises
    ------
    GdfeError
        For an empty text, or a letter without a glyph (naming its position).
    """
    if not isinstance(text, str):
        raise GdfeTypeError(f"text: expected a string of letters, got {text!r}")
    out = []
    for k, ch in enumerate(text):
        if ch.isspace():
            continue
        try:
            out.append(glyph(ch))
        except GdfeError as exc:
            raise GdfeError(f"text[{k}]: {str(exc).removeprefix('letter: ')}") from None
    if not out:
        raise GdfeError(f"text: expected at least one letter, got {text!r}")
    return out

