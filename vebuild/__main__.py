"""``python -m vebuild``: the command line, as the ``vebuild`` script runs it."""

import sys

from vebuild.cli import main

sys.exit(main(sys.argv[1:]))
