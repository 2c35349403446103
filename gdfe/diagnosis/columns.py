"""What the diagnosis knows about a table's extra columns: their declared roles.

A numeric column whose values the fold follows monotonically could be a process variable
(the oven's temperature: the film shrank less where it was cooler) or something else
entirely (the angle of the hinge to the film's draw direction, the panels' length, a
specimen number): the data alone cannot tell. So an extra column is credited with a physical
cause only when the user declares what it is, with a role from :data:`ROLES`:

* **process** roles (``oven_temperature``, ``oven_time``, ``exposure``, ``heating_rate``):
  the column is a process variable, and a monotone dependence on it is
  ``partial_activation[COLUMN]``, "the process fell short";
* **group** roles (``film_lot``, ``printer``, ``batch``, ``operator``): the column labels
  batches of the process, and a per-group contraction is ``batch[COLUMN]``;
* other roles (``angle_to_draw_direction``, ``panel_length``, ``sample``, ``specimen``,
  ``position``): the column is known, but no effect of the catalogue is its physics.

An undeclared numeric column, or one with another role, is a **factor**: the same monotone
fit is made, but it is named ``factor[COLUMN]`` ("the fold changes monotonically with
COLUMN; what COLUMN is was not declared"), of kind ``"factor"``; an undeclared text column
gives a **group factor**, also ``factor[COLUMN]`` (a column is numeric or text, never both), of kind ``"factor"``. The fitting
is the catalogue's ``partial_activation`` and ``batch`` (:mod:`gdfe.diagnosis.effects`);
only the name, the kind and the credit differ.
"""

from __future__ import annotations

import dataclasses
import re

from gdfe._validation import GdfeError, GdfeTypeError
from gdfe.diagnosis.effects import EFFECTS

__all__ = ["ROLES", "PROCESS", "GROUP", "OTHER", "ColumnRoles", "check_roles", "parse_role", "rename", "FACTOR_KIND"]

PROCESS, GROUP, OTHER = "process", "group", "other"
#: The kind of an effect on a column whose role was not declared (or is not a process or group role).
FACTOR_KIND = "factor"

#: Declarable roles: role -> (kind, what it is).
ROLES = {
    "oven_temperature": (PROCESS, "the temperature of the oven the film was activated in"),
    "oven_time": (PROCESS, "how long the film was heated"),
    "exposure": (PROCESS, "the exposure of the print (light dose, layer cure time)"),
    "heating_rate": (PROCESS, "how fast the film was heated"),
    "film_lot": (GROUP, "the lot of pre-strained film"),
    "printer": (GROUP, "the printer that made the part"),
    "batch": (GROUP, "the print or oven batch"),
    "operator": (GROUP, "who made or measured the part"),
    "angle_to_draw_direction": (OTHER, "the angle of the hinge to the film's draw direction (an anisotropic "
                                       "pre-strain, not a process shortfall)"),
    "panel_length": (OTHER, "the length of the panels (their sag or weight, not a process shortfall)"),
    "sample": (OTHER, "the specimen a test was made on"),
    "specimen": (OTHER, "the specimen a test was made on"),
    "position": (OTHER, "where on the sheet the part was printed"),
}


def check_roles(roles, columns):
    """Validate declared roles: a dict of column name -> role name from :data:`ROLES`.

    Parameters
    ----------
    roles : dict of str -> str or None
    columns : sequence of str
        The extra columns of the tests.

    Returns
    -------
    dict of str -> str
    """
    if roles is None:
        return {}
    if not isinstance(roles, dict):
        raise GdfeTypeError(f"roles: expected a dict of column name -> role, got {type(roles).__name__}")
    out = {}
    for col, role in roles.items():
        if not isinstance(col, str) or not isinstance(role, str):
            raise GdfeTypeError(f"roles: expected column and role names (str), got {col!r}: {role!r}")
        if col not in columns:
            raise GdfeError(f"roles: no column {col!r} in the tests; columns besides L_mm, d_mm, h_mm, alpha_rad: "
                            f"{', '.join(columns) or 'none'}")
        if role not in ROLES:
            raise GdfeError(f"roles: expected a role of {', '.join(ROLES)} for column {col!r}, got {role!r}")
        out[col] = role
    return out


def parse_role(text):
    """``"COLUMN=ROLE"`` (the command line's ``--role``) as ``(column, role)``."""
    col, eq, role = str(text).partition("=")
    if not eq or not col.strip() or not role.strip():
        raise GdfeError(f"--role: expected COLUMN=ROLE (roles: {', '.join(ROLES)}), got {text!r}")
    return col.strip(), role.strip()


@dataclasses.dataclass(frozen=True)
class ColumnRoles:
    """The declared roles of a table's columns, and what follows for the effects' names.

    Attributes
    ----------
    roles : dict of str -> str
        Declared column -> role (:data:`ROLES`).
    """

    roles: dict = dataclasses.field(default_factory=dict)

    def kind(self, column):
        """``"process"``, ``"group"`` or ``"other"`` for a declared column, None when undeclared."""
        role = self.roles.get(column)
        return None if role is None else ROLES[role][0]

    def is_process(self, column):
        return self.kind(column) == PROCESS

    def is_group(self, column):
        return self.kind(column) == GROUP

    def effect_kinds(self, model):
        """The kind (:data:`gdfe.diagnosis.effects.KINDS`) of each effect of ``model``:
        ``"factor"`` for ``partial_activation`` on a column not declared a process role and for
        ``batch`` on one not declared a group role, else the catalogue's kind of the effect
        (``"physics"``, ``"measurement"``)."""
        out = []
        for e in model.effects:
            if (e == "partial_activation" and not self.is_process(model.process)) or \
                    (e == "batch" and not self.is_group(model.group)):
                out.append(FACTOR_KIND)
            else:
                out.append(getattr(EFFECTS.get(e), "kind", None) or "physics")
        return out

    def renames(self, models):
        """Fitted name -> reported name of the column effects of ``models`` that are factors:
        ``partial_activation[C] -> factor[C]``, ``batch[C] -> factor[C]``."""
        out = {}
        for m in models:
            if getattr(m, "process", None) and not self.is_process(m.process):
                out[f"partial_activation[{m.process}]"] = f"factor[{m.process}]"
            if getattr(m, "group", None) and not self.is_group(m.group):
                out[f"batch[{m.group}]"] = f"factor[{m.group}]"
        return out

    def words(self, column, numeric=True):
        """What a column is, in words, for the credit of an effect on it."""
        role = self.roles.get(column)
        if role is None:
            return (f"a factor of {column}: the fold changes monotonically with {column}; what {column} is was not "
                    f"declared (declare it with --role {column}=ROLE, e.g. oven_temperature for a process "
                    f"variable)" if numeric else
                    f"a group factor of {column}: the tests of each {column} fold by their own factor; what "
                    f"{column} is was not declared (declare it, e.g. --role {column}=film_lot)")
        kind, what = ROLES[role]
        if kind == PROCESS:
            return f"{column} is {what} (declared {role}): the process fell short"
        if kind == GROUP:
            return f"{column} is {what} (declared {role}): a batch-to-batch difference of the contraction"
        return (f"{'a factor' if numeric else 'a group factor'} of {column}, declared {role} ({what}): no effect "
                f"of the catalogue is its physics, so the fit says only that the fold changes with it")


def rename(text, renames):
    """``text`` with every fitted name of ``renames`` replaced by its reported name."""
    if not renames or not isinstance(text, str):
        return text
    pattern = re.compile("|".join(re.escape(k) for k in sorted(renames, key=len, reverse=True)))
    return pattern.sub(lambda m: renames[m.group(0)], text)
