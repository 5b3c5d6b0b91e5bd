"""``python -m napari_pfsdm``: the same as the ``pfsdm`` command."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
