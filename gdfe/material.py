"""The material of a cell: which faces of the film carry passive material.

==================  ===========  ==============  =====================================
material            top coated   bottom coated   what the film does on heating
==================  ===========  ==============  =====================================
``RIGID``           yes          yes             keeps its shape (R-GDFE)
``CONTRACT_TOP``    no           yes             top face shrinks by R: bends towards +z
``CONTRACT_BOTTOM`` yes          no              bottom face shrinks by R: bends towards -z
``FREE_SHRINK``     no           no              shrinks uniformly by R in-plane
==================  ===========  ==============  =====================================
"""

from __future__ import annotations

import enum

__all__ = ["Material", "LAYOUT_CHARS"]


class Material(enum.IntEnum):
    """Material of a cell, by which faces carry passive material."""

    RIGID = 0
    CONTRACT_TOP = 1
    CONTRACT_BOTTOM = 2
    FREE_SHRINK = 3


#: Characters of the text layout of a design (``from_rows`` and TOML ``rows``).
LAYOUT_CHARS = {"R": Material.RIGID, "T": Material.CONTRACT_TOP, "B": Material.CONTRACT_BOTTOM,
                "S": Material.FREE_SHRINK}
