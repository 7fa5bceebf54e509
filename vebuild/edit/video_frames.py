"""Choosing a frame of a video in the screen's file browser, without a window.

:class:`VideoFrames` holds the video's frames in presentation order (their times, read once from the
stream's packets: vebuild/project/video.py), the frame shown (its index and time), and that frame's
pixels, decoded exactly when first shown. Stepping moves one frame back or on; the frame shown is
added through :meth:`vebuild.edit.session.EditSession.add_video_still` (a lossless PNG beside the
video, its origin recorded: docs/video-stills.md).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vebuild.errors import VebuildError
from vebuild.project.images import sha256_file
from vebuild.project.video import FrameTimes, Still, decode_still, frame_times


@dataclass
class VideoFrames:
    """A video file, its frames, and the one shown (``index``, from 0)."""

    path: Path
    folder: Path  # the project's: the origin names the video relative to it
    times: FrameTimes | None = None
    index: int = 0
    error: str = ""
    _sha256: str | None = None
    _still: Still | None = field(default=None, repr=False)

    @classmethod
    def open(cls, path: str | os.PathLike[str], folder: str | os.PathLike[str]) -> VideoFrames:
        """The video's frames (the first shown); a VebuildError naming the file where it is no video."""
        path = Path(os.path.abspath(path))
        times = frame_times(path, "the frame chooser")
        return cls(path, Path(folder), times, 0, "", sha256_file(path))

    @property
    def count(self) -> int:
        return len(self.times.pts) if self.times is not None else 0

    @property
    def time(self) -> float:
        return self.times.time(self.index) if self.times is not None else 0.0

    def step(self, by: int) -> None:
        """Show the frame ``by`` frames on (back, if negative), stopping at the first and the last."""
        self.go(self.index + by)

    def go(self, index: int) -> None:
        index = max(0, min(self.count - 1, index))
        if index != self.index:
            self.index, self._still, self.error = index, None, ""

    def still(self) -> Still | None:
        """The frame shown, decoded exactly (once); None with ``error`` said where it cannot be."""
        if self._still is None and not self.error:
            try:
                self._still = decode_still(self.path, self.folder, frame=self.index, times=self.times,
                                           sha256=self._sha256)
            except VebuildError as e:
                self.error = str(e)
        return self._still

    def label(self) -> str:
        """What the chooser says of the frame shown."""
        still = self.still()
        combed = " (interlaced)" if still is not None and still.origin["interlaced"] else ""
        return (f"{self.path.name}: frame {self.index} (of 0 to {self.count - 1}) at {self.time:.3f} s{combed}; "
                ", and . (or Left and Right) step a frame")

    def add(self, session: Any, field: str | None = None) -> str:
        """Add the frame shown to the project as a still; its photo id."""
        return str(session.add_video_still(self.path, self.index, field))
