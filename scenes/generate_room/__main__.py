"""``python scenes/generate_room`` (or ``python -m scenes.generate_room``): regenerate scenes/room."""

import sys
from pathlib import Path

if not __package__:  # run as a folder: import the package from its parent, not its modules one by one
    sys.path[0] = str(Path(__file__).resolve().parent.parent)
    from generate_room import main
else:
    from . import main

main()
