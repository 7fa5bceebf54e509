"""What each result was computed from, whether it is still current, and the audit trail (layer 3).

Three stages write results into the project: ``calibration`` (``vebuild calibrate``, and
``vebuild register`` for the photos it places), ``model_solution`` (``vebuild solve``, which also
writes the solved values back into ``model.nodes``) and ``textures`` (``vebuild texture``). Each
record carries ``computed_from``: a dict of named SHA-256 hashes of exactly what that stage read
(:func:`stamp`). :func:`stale` hashes the same things in the document as it is now and names each
result whose inputs changed, why, and the command that brings it up to date.

What each stage reads (the names in ``computed_from``; scenes/FORMAT.md, "Provenance"):

- ``calibration``: per photo ``photos/ID/image`` (``file``, ``width``, ``height``, ``sha256``),
  ``photos/ID/camera`` (``exif``, ``focal_px``, ``principal_point``, ``camera_height``),
  ``photos/ID/marks`` (``vanishing_segments``, ``marker_observations`` and the ``known_lengths``
  clicked in it), and for a photo placed by ``vebuild register`` also ``photos/ID/pins`` (its pins);
  then ``markers``, ``origin_marker``, ``reference_distances`` and ``settings``.
- ``model_solution``: ``model/nodes/NAME`` per node (as written after the solve), ``model/pins``,
  ``model/edge_observations``, ``markers``, ``reference_distances``, ``settings``, and the
  calibration it started from: ``calibration/cameras/ID`` per camera and ``calibration/markers``
  and ``calibration/other`` (the rest of the record, without its ``computed_from`` and
  ``input_sha256``).
- ``textures``: ``model/nodes/NAME`` per node, ``model_solution`` (the record without its
  ``computed_from``), ``cameras/ID`` per camera it could use (the final camera record:
  ``decode.camera_records``), and ``photos/ID/image`` per photo.

Nothing else is an input: ``views``, ``lighting``, ``hypotheses``, ``evidence_markers``,
``analyses``, ``name``, ``audit`` and each stage's own results never make a stage stale. A stage's
own later output is not its input either, so a later stage never makes an earlier one stale, and a
re-run on unchanged inputs stamps the same hashes. A registered photo's camera was placed from the
solved model; a later solve reads it as a prior, so a solve does not make it stale (only its pins,
its marks or its image do).

The audit trail (top-level ``audit``) is a list of entries, one per command that changed the
project: ``command``, ``arguments`` (the words after the command, those that name a file or
folder written relative to the project's folder: :func:`audit_entry`), ``vebuild`` (version),
``time`` (UTC, ISO 8601), ``before_sha256`` and ``after_sha256``: :func:`document_sha256` of the
document before the command and as written, that is SHA-256 of the UTF-8 bytes of
``json.dumps(doc_without_audit, sort_keys=True, separators=(",", ":"), ensure_ascii=False)``.
:func:`verify_audit` checks the chain.

Every output (renders, exports, videos, the report, analyses' figures) names the project state it
was made from by :func:`inputs_sha256`, the same hash: the document's inputs and results without
the audit trail, whose times and words differ from one examiner's run to another's. Two copies of a
project taken through the same commands, in any folders, at any time, give the same outputs, byte
for byte (tests/test_determinism.py).
"""

from __future__ import annotations

import contextlib
import contextvars
import datetime
import hashlib
import json
import os
import shlex
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .camera_records import camera_records

__all__ = ["READS", "STAGES", "TITLES", "AuditProblem", "Stale", "audit_entry", "command_context", "current_command",
           "document_sha256", "inputs", "inputs_sha256", "stage_hashes", "stale", "stale_line", "stale_record",
           "stale_warnings", "stamp", "verify_audit"]

#: The stages, in the order they are run; each reads the results of those before it.
STAGES = ("calibration", "model_solution", "textures")
_VERB = {"calibration": "calibrating", "model_solution": "solving", "textures": "texturing"}
_PHOTO_PARTS = {"image": ("file", "width", "height", "sha256"),
                "camera": ("exif", "own_camera", "focal_px", "principal_point", "camera_height"),
                "marks": ("vanishing_segments", "vanishing_segment_sigmas", "marker_observations",
                          "x_axis_unresolved")}
_LATER = ("vanishing_segment_sigmas", "own_camera", "x_axis_unresolved")
_SHOWN = 3  # differences named in one reason; the rest are counted


def _sha(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def document_sha256(data: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of the document without its ``audit``: what an audit entry's hashes are of."""
    return _sha({k: v for k, v in data.items() if k != "audit"})


def inputs_sha256(data: Mapping[str, Any]) -> str:
    """The inputs digest that every output embeds (``vebuild:inputs_sha256``; FORMAT.md, "Inputs
    digest"): SHA-256 (hex) of the document without its ``audit``, as :func:`document_sha256`.

    It covers every input and result the document holds (the photos by their recorded ``sha256``,
    which each command checks against the files before it reads them; the texture pages by their
    ``atlas_sha256``; the calibration, the solution) and nothing of the audit trail, whose times
    and words are the examiner's, not the evidence's. It is the ``after_sha256`` of the audit
    entry that wrote the state an output was made from, so the trail says which command that was.
    """
    return document_sha256(data)


# --------------------------------------------------------------------------------------------------
# What each stage read


def _photo_hashes(data: Mapping[str, Any], registered: set[str]) -> dict[str, str]:
    out = {}
    pins = (data.get("model") or {}).get("pins") or []
    lengths = data.get("known_lengths") or []
    for p in data.get("photos") or []:
        pid = p["id"]
        for part, keys in _PHOTO_PARTS.items():
            # vanishing_segment_sigmas, own_camera and x_axis_unresolved (later than the others) count
            # where present: older hashes stand.
            value: dict[str, Any] = {k: p.get(k) for k in keys if k not in _LATER or k in p}
            if part == "marks":
                value["known_lengths"] = [k for k in lengths if k.get("photo") == pid]
            out[f"photos/{pid}/{part}"] = _sha(value)
        if pid in registered:
            out[f"photos/{pid}/pins"] = _sha([q for q in pins if q.get("photo") == pid])
    return out


def _without(record: Any, *keys: str) -> Any:
    return {k: v for k, v in record.items() if k not in keys} if isinstance(record, Mapping) else record


def _model_hashes(data: Mapping[str, Any]) -> dict[str, str]:
    model = data.get("model") or {}
    return {f"model/nodes/{n.get('name')}": _sha(n) for n in model.get("nodes") or []}


def inputs(data: Mapping[str, Any], stage: str) -> dict[str, str]:
    """The named SHA-256 hashes of what ``stage`` reads, in the document as it is now."""
    if stage == "calibration":
        cal = data.get("calibration") or {}
        registered = {pid for pid, c in (cal.get("cameras") or {}).items()
                      if isinstance(c, Mapping) and c.get("mode") == "registered"}
        out = _photo_hashes(data, registered)
        for key in ("markers", "origin_marker", "reference_distances", "settings"):
            out[key] = _sha(data.get(key))
        if "camera_groups" in data:  # the user's camera groups, where there are any
            out["camera_groups"] = _sha(data["camera_groups"])
        return out
    if stage == "model_solution":
        model = data.get("model") or {}
        out = _model_hashes(data)
        out["model/pins"] = _sha(model.get("pins"))
        out["model/edge_observations"] = _sha(model.get("edge_observations"))
        for key in ("markers", "reference_distances", "settings"):
            out[key] = _sha(data.get(key))
        cal = data.get("calibration") or {}
        for pid, rec in (cal.get("cameras") or {}).items():
            out[f"calibration/cameras/{pid}"] = _sha(rec)
        out["calibration/markers"] = _sha(cal.get("markers"))
        # Not its stamps: the older whole-document hash (input_sha256) moves with the solved model.
        out["calibration/other"] = _sha(_without(cal, "cameras", "markers", "computed_from", "input_sha256"))
        used = [s for s in data.get("scans") or [] if isinstance(s, Mapping) and s.get("use_in_solve")]
        if used:  # laser scans the solve observed (FORMAT.md "Laser scans"): only where there are any
            out["scans/use_in_solve"] = _sha(used)
        return out
    if stage == "textures":
        out = _model_hashes(data)
        out["model_solution"] = _sha(_without(data.get("model_solution"), "computed_from"))
        for pid, rec in camera_records(data).items():
            out[f"cameras/{pid}"] = _sha(rec)
        out.update({k: v for k, v in _photo_hashes(data, set()).items() if k.endswith("/image")})
        return out
    raise ValueError(f"unknown stage {stage!r} (the stages are {', '.join(STAGES)})")


def stamp(data: dict[str, Any], stage: str, photos: Sequence[str] | None = None) -> None:
    """Write ``data[stage]["computed_from"]``: the hashes of what the stage just read.

    ``photos`` (``vebuild register``): only those photos' entries are stamped again; the rest of
    an earlier stamp is kept, so that registering a photo does not make a stale calibration of the
    other photos look current.
    """
    now = inputs(data, stage)
    if photos is not None:
        old = dict(data[stage].get("computed_from") or {})
        if not old:  # a calibration from before provenance: the whole of it is not known to be current
            return
        mine = {k for k in now if any(k.startswith(f"photos/{p}/") for p in photos)}
        old = {k: v for k, v in old.items() if not any(k.startswith(f"photos/{p}/") for p in photos)}
        now = {**old, **{k: now[k] for k in sorted(mine)}}
    data[stage]["computed_from"] = dict(sorted(now.items()))


# --------------------------------------------------------------------------------------------------
# Stale results


@dataclass(frozen=True)
class Stale:
    """A result that is not current: its ``stage``, the ``reason`` (what changed, in plain words)
    and the ``command`` that brings it up to date."""

    stage: str
    reason: str
    command: str

    @property
    def message(self) -> str:
        verb = "are" if self.stage == "textures" else "is"
        return f"{TITLES[self.stage]} {verb} stale: {self.reason}; run `{self.command}`"


#: Each stage's name in a sentence.
TITLES = {"calibration": "the calibration", "model_solution": "the model's solution", "textures": "the textures"}


def _describe(key: str) -> str:
    """An input's name in words (a name vebuild does not write, from an edited file, as it is)."""
    parts = key.split("/")
    if parts[0] == "photos" and len(parts) == 3:
        pid, part = parts[1], parts[2]
        return {"image": f"the image of photo {pid}", "camera": f"the camera data of photo {pid} (EXIF, focal "
                "length, principal point or height)", "marks": f"the marks of photo {pid}",
                "pins": f"the pins of photo {pid}"}.get(part, key)
    if parts[0] == "model" and len(parts) > 2 and parts[1] == "nodes":
        return f"node {'/'.join(parts[2:])} of the model"
    if key.startswith("calibration/cameras/") and len(parts) == 3:
        return f"the calibrated camera of photo {parts[2]}"
    if key.startswith("cameras/") and len(parts) == 2:
        return f"the camera of photo {parts[1]}"
    return {"model/pins": "the model's pins", "model/edge_observations": "the model's edge observations",
            "calibration/markers": "the calibrated markers", "calibration/other": "the calibration record",
            "model_solution": "the model's solution", "origin_marker": "the origin marker",
            "reference_distances": "the reference distances", "settings": "the settings",
            "markers": "the markers", "scans/use_in_solve": "the laser scans used in the solve"}.get(key, key)


def _differences(recorded: Mapping[str, Any], now: Mapping[str, str], stage: str) -> list[str]:
    verb = _VERB[stage]
    out = []
    whole = {}  # photos added or removed as a whole: named once
    for key in sorted(set(recorded) ^ set(now)):
        if key.startswith("photos/") and key.endswith("/image") and key.count("/") == 2:
            whole[key.split("/")[1]] = "added" if key in now else "removed"
            out.append(f"photo {key.split('/')[1]} was {whole[key.split('/')[1]]} after {verb}")
    for key in sorted(set(recorded) | set(now)):
        if key.startswith("photos/") and key.count("/") == 2 and key.split("/")[1] in whole:
            continue
        if key not in now:
            out.append(f"{_describe(key)} was removed after {verb}")
        elif key not in recorded:
            out.append(f"{_describe(key)} was added after {verb}")
        elif recorded[key] != now[key]:
            out.append(f"{_describe(key)} changed after {verb}")
    if len(out) > _SHOWN:
        out = out[:_SHOWN] + [f"and {len(out) - _SHOWN} more"]
    return out


def _command(stage: str, data: Mapping[str, Any], project: str) -> str:
    project = shlex.quote(project)
    if stage == "calibration":
        return f"vebuild calibrate {project}"
    if stage == "model_solution":
        recal = " --recalibrate" if (data.get("model_solution") or {}).get("recalibrated") else ""
        return f"vebuild solve {project}{recal}"
    return f"vebuild texture {project}"


def stale(data: Mapping[str, Any], project: str = "PROJECT") -> list[Stale]:
    """The results of ``data`` that are not current, in stage order.

    A result is stale when what it read changed since it was made, when an earlier stage's result
    it read is stale (that reason given), or when it records no ``computed_from`` (made before
    vebuild recorded it: not known to be current). ``project``: the project file as the commands
    should name it.
    """
    out: list[Stale] = []
    behind: Stale | None = None  # the earliest stale stage before this one
    commands: list[str] = []
    for stage in STAGES:
        record = data.get(stage)
        if not isinstance(record, Mapping):
            continue
        mine = _command(stage, data, project)
        recorded = record.get("computed_from")
        reasons = []
        if not isinstance(recorded, Mapping):
            reasons.append("it was made before vebuild recorded what results are computed from, so it is not "
                           "known to be current")
        else:
            reasons += _differences(recorded, inputs(data, stage), stage)
        if behind is not None:
            reasons.append(f"it was computed from {TITLES[behind.stage]}, which is stale ({behind.reason})")
        if reasons:
            s = Stale(stage, "; ".join(reasons), " && ".join([*commands, mine]))
            out.append(s)
            behind = behind or s
            commands = [*commands, mine]
    return out


# --------------------------------------------------------------------------------------------------
# The audit trail


@dataclass(frozen=True)
class _Running:
    command: str
    arguments: tuple[str, ...]
    paths: frozenset[str]  # the words the command line reads as files or folders
    cwd: str | None  # the working directory the words are relative to


_COMMAND: contextvars.ContextVar[_Running | None] = contextvars.ContextVar("vebuild_command", default=None)


def _cwd() -> str | None:
    try:
        return os.getcwd()
    except OSError:  # the working directory was removed: the words are kept as given
        return None


@contextlib.contextmanager
def command_context(command: str, arguments: Sequence[str], paths: Iterable[str] = ()) -> Iterator[None]:
    """While this holds, every save of a project file appends an audit entry for this command.

    ``paths``: the values of the arguments that name a file or folder (the command line's parser
    knows which); a word equal to one, and a word that names the project file itself, is recorded
    relative to the project's folder (:func:`audit_entry`).
    """
    token = _COMMAND.set(_Running(command, tuple(arguments), frozenset(paths), _cwd()))
    try:
        yield
    finally:
        _COMMAND.reset(token)


def current_command() -> tuple[str, tuple[str, ...]] | None:
    """The command being run (name, arguments), if a :func:`command_context` holds."""
    running = _COMMAND.get()
    return None if running is None else (running.command, running.arguments)


def _project_relative(word: str, folder: str, cwd: str) -> str:
    """``word`` (a path relative to ``cwd``, or absolute) relative to the project's ``folder``, in
    POSIX form; the absolute path where it lies outside the folder."""
    full = os.path.realpath(os.path.join(cwd, word))
    try:
        rel = os.path.relpath(full, folder)
    except ValueError:  # another drive (Windows)
        return full
    if rel == os.pardir or rel.startswith(os.pardir + os.sep) or os.path.isabs(rel):
        return full
    return rel.replace(os.sep, "/")


def _recorded_words(arguments: Sequence[str], project: str | os.PathLike[str] | None) -> list[str]:
    """The words as the audit records them: a path (an argument the parser reads as one, or the
    project file) relative to the project's folder, or absolute where outside it; the rest as given.
    An option's value given after ``=`` (``--out=FILE``) counts as a word of its own."""
    running = _COMMAND.get()
    cwd = None if running is None else running.cwd
    if project is None or cwd is None:
        return list(arguments)
    me = os.path.realpath(os.path.join(cwd, os.fspath(project)))
    folder = os.path.dirname(me)
    paths = running.paths if running is not None else frozenset()

    def one(word: str) -> str:
        if not word:
            return word
        if word in paths or os.path.realpath(os.path.join(cwd, word)) == me:
            return _project_relative(word, folder, cwd)
        option, eq, value = word.partition("=")
        if option.startswith("--") and eq and value in paths:
            return f"{option}={_project_relative(value, folder, cwd)}"
        return word

    return [one(w) for w in arguments]


def audit_entry(command: str, arguments: Sequence[str], before: str | None, after: str,
                project: str | os.PathLike[str] | None = None) -> dict[str, Any]:
    """One audit entry (FORMAT.md, "Audit trail") for a save of the project file ``project``.

    Its time is now, or, where the environment sets ``SOURCE_DATE_EPOCH`` (the reproducible-builds
    convention: seconds since 1970 UTC), that time. A word that names a file or folder (an argument
    the command line reads as a path, given to :func:`command_context`, or the project file) is
    recorded relative to the project's folder, POSIX style (``room.vebuild.json``,
    ``renders/a.png``), whatever the working directory, so that two examiners' trails agree; one
    outside the folder is recorded as its absolute path (it starts with ``/`` or a drive, which a
    path inside never does). Without ``project`` or outside a command the words are kept as given.
    """
    from vebuild import __version__

    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    when = (datetime.datetime.fromtimestamp(int(epoch), datetime.UTC) if epoch.isdigit()
            else datetime.datetime.now(datetime.UTC))
    time = when.replace(microsecond=0).isoformat().replace("+00:00", "Z")
    # A word the shell gave as bytes that are not UTF-8 (a file name) is kept with those bytes as \xNN.
    words = [os.fsencode(a).decode("utf-8", "backslashreplace") for a in _recorded_words(arguments, project)]
    return {"command": command, "arguments": words, "vebuild": __version__, "time": time,
            "before_sha256": before, "after_sha256": after}


@dataclass(frozen=True)
class AuditProblem:
    """A break in the audit trail: ``index`` the entry after which the document changed outside
    vebuild (-1: before the first; the trail's length: after the last), ``message`` what was found."""

    index: int
    message: str


def verify_audit(data: Mapping[str, Any]) -> list[AuditProblem]:
    """The breaks in the audit chain: an entry whose ``before_sha256`` is not the previous entry's
    ``after_sha256``, and a document that is not the last entry's ``after_sha256``."""
    trail = data.get("audit") or []
    out = []
    for i in range(1, len(trail)):
        before, prev = trail[i]["before_sha256"], trail[i - 1]
        if before is not None and before != prev["after_sha256"]:
            out.append(AuditProblem(i - 1, f"the project was changed outside vebuild between `{prev['command']}` "
                                    f"({prev['time']}) and `{trail[i]['command']}` ({trail[i]['time']}): "
                                    f"audit[{i}].before_sha256 is not audit[{i - 1}].after_sha256"))
    if trail:
        last = trail[-1]
        found = document_sha256(data)
        if found != last["after_sha256"]:
            out.append(AuditProblem(len(trail), f"the project was changed outside vebuild after its last recorded "
                                    f"command, `{last['command']}` ({last['time']}): the file hashes to "
                                    f"{found[:12]}…, the trail's last after_sha256 is "
                                    f"{last['after_sha256'][:12]}…"))
    return out


# --------------------------------------------------------------------------------------------------
# What the commands say


#: The stages whose results each command reads (and does not make again itself): a stale one is
#: named in a warning before the command runs. Every command still runs: the user may want to see
#: the old result, and each output of a stale project says it is stale (the report's banner, the
#: render's PNG text, the screens' status lines).
READS = {"solve": ("calibration",), "register": ("calibration", "model_solution"),
         "texture": ("calibration", "model_solution")}
_ALL = STAGES


def stale_warnings(project: Any, command: str) -> list[str]:
    """``warning: …`` lines for the stale results that ``command`` reads, for a Project."""
    reads = READS.get(command, _ALL)
    return [f"warning: {s.message}" for s in stale(project.data, str(project.path)) if s.stage in reads]


def stage_hashes(data: Mapping[str, Any]) -> dict[str, str]:
    """SHA-256 of each stage's record present (the results an output used), by stage."""
    return {s: _sha(data[s]) for s in STAGES if isinstance(data.get(s), Mapping)}


def stale_record(data: Mapping[str, Any]) -> dict[str, str]:
    """The stale stages, each with its reason: what an output made from them records."""
    return {s.stage: s.reason for s in stale(data)}


def stale_line(found: Sequence[Stale]) -> str | None:
    """One short line for a screen's status: which results are stale and what updates them (the
    full messages go in its tooltip or the panel), or None when all are current."""
    if not found:
        return None
    steps = [c.split(" ", 2)[1] for c in found[-1].command.split(" && ")]
    return (f"STALE: {', '.join(TITLES[s.stage].removeprefix('the ') for s in found)}: "
            f"{' then '.join(steps)} again")
