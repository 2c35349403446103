"""A Griffe extension for the API reference: Sphinx roles in docstrings shown as code.

The docstrings cross-reference with Sphinx roles (:func:`gdfe.hinge`, :data:`TABLE1`), which
Markdown would show literally; this turns each into inline code (`gdfe.hinge`). Loaded by
mkdocstrings (``extensions`` in mkdocs.yml); nothing in the library depends on it.
"""

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|meth|class|mod|data|attr|obj|exc|const|ref|term):`~?([^`]+)`")


class SphinxRoles(griffe.Extension):
    """Replace ``:role:`target``` by ```target``` in every docstring Griffe loads."""

    def on_instance(self, *, obj, **kwargs):
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(r"`\1`", obj.docstring.value)
