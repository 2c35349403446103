import sys

from gdfe.cli import main

sys.exit(main())
