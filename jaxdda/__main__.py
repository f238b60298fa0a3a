"""``python -m jaxdda run ...``: the same as the ``jaxdda`` command."""
import sys

from jaxdda.cli import main

sys.exit(main())
