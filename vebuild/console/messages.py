"""An error's message as the command line prints it: the place in the project file named in
words (``photo 'door', field "width"``) beside the JSON path an error raised after loading gives."""

from __future__ import annotations

import json
from pathlib import Path

from vebuild.errors import ProjectError, VebuildError
from vebuild.project.json_paths import field_words


def error_in_words(e: VebuildError) -> str:
    """The error's message, naming the place in the project file in words where it gives a JSON path."""
    if not isinstance(e, ProjectError) or e.words or not e.where.startswith("$."):
        return str(e)
    try:
        path = Path(e.file)
        if not path.name.endswith(".json") or path.stat().st_size > 256 * 2**20:
            return str(e)
        return str(e.named(field_words(e.where, json.loads(path.read_text("utf-8")))))
    except (OSError, ValueError, RecursionError):  # unreadable, not JSON, nested too deep: as it was
        return str(e)
