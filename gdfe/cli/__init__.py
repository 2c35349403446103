"""The ``gdfe`` command line, the application layer above the library.

One module per subcommand (``hinge``, ``simulate``, ``fem``, ``study``, ``report``,
``calibrate``, ``diagnose``, ``bench``); :func:`main` takes ``argv`` so that tests call
``main([...])``. This package is the only code that may import ``studies`` and
``reference_fem``; the library (``gdfe`` outside this package) never imports it.
"""

from gdfe.cli._main import build_parser, main

__all__ = ["main", "build_parser"]
