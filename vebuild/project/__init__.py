"""The project layer (layer 3 of DESIGN.md): the project file and what is read from and written to it.

- :mod:`.file`: the file itself (load, validate, save), its photos verified, its texture pages read;
- :mod:`.validation`: the schema, the bounds and the JSON text's faults located;
- :mod:`.images`: the one bounded image reader, photo hashes, EXIF;
- :mod:`.decode`: the document turned into domain objects (cameras, markers, the model with its
  pins and edges, the solution, views, lighting, texture pages), each decoded in this one place;
- :mod:`.records`: what results are written as (plain JSON numbers, camera and view records);
- :mod:`.atomic`: the one writer of files (a temporary name beside the target, renamed over it);
- :mod:`.outputs`: the output policy (what a stage may overwrite) and manifests.

The names below are the file's, re-exported so that ``from vebuild.project import load_project``
reads as before; the other modules are imported by their own names.
"""

from .file import (
    AS_PHOTOGRAPHED,
    DEFAULT_SETTINGS,
    FORMAT,
    MAX_IMAGE_PIXELS,
    RESULT_KEYS,
    VERSION,
    Project,
    autosave_path,
    canonical_input_hash,
    decode_texture_page,
    json_path,
    load_project,
    new_photo_entry,
    new_project,
    open_image,
    read_exif,
    read_texture_page,
    save_project,
    schema,
    sha256_bytes,
    sha256_file,
    texture_page_path,
    validate,
)

__all__ = [
    "AS_PHOTOGRAPHED", "DEFAULT_SETTINGS", "FORMAT", "MAX_IMAGE_PIXELS", "RESULT_KEYS", "VERSION", "Project",
    "autosave_path", "canonical_input_hash", "decode_texture_page", "json_path", "load_project",
    "new_photo_entry", "new_project", "open_image", "read_exif", "read_texture_page", "save_project",
    "schema", "sha256_bytes", "sha256_file", "texture_page_path", "validate",
]
