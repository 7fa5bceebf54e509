"""Where the files that ship with vebuild live: GLSL shaders and the bundled example project.

An installed wheel carries them under ``vebuild/_data`` (see pyproject.toml); a source checkout
(or an editable install) has them at the top of the repository.
"""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def data_dir(name: str) -> Path:
    """The folder ``name`` (e.g. 'shaders', 'scenes/room'), installed or in the checkout."""
    for base in (_PACKAGE / "_data", _PACKAGE.parent):
        if (base / name).is_dir():
            return base / name
    raise FileNotFoundError(f"vebuild's data folder '{name}' is missing from this installation")


def example_project_dir() -> Path:
    """The bundled example room: photos, project file and ground truth."""
    return data_dir("scenes/room")


def package_data_file(name: str) -> Path:
    """A data file shipped inside the package, in ``vebuild/data`` (e.g. 'sensors.csv', the sensor
    database of :mod:`vebuild.calibration.exif`)."""
    path = _PACKAGE / "data" / name
    if not path.is_file():
        raise FileNotFoundError(f"vebuild's data file 'data/{name}' is missing from this installation")
    return path


def cache_dir() -> Path:
    """The user's cache of what vebuild can make again (``~/.cache/vebuild``; ``VEBUILD_CACHE``
    overrides it): generated benchmark scenes, the sizes of photos already decoded whole."""
    return Path(os.environ.get("VEBUILD_CACHE") or Path.home() / ".cache" / "vebuild")
