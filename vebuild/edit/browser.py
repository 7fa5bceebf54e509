"""Photos added from a file browser inside the modelling screen (no desktop dialog program), and
from files dropped onto its window.

:class:`FileBrowser` is the browser's state without a window: the folder shown, its sub-folders
and the image files vebuild reads (:data:`~vebuild.edit.session.PHOTO_SUFFIXES`: JPEG, PNG, TIFF
and camera RAW; hidden ones left out), the files picked, a typed folder to go to. :func:`add_files`
adds chosen files through the session's :meth:`~vebuild.edit.session.EditSession.add_photo` (the
same code as the strip's Add photo: the size, SHA-256 and EXIF recorded, the file itself never
changed), and names each that cannot be added, and why. :class:`PhotoBrowser`, a part of the
:class:`~vebuild.edit.screen.Editor`, opens the browser, adds what is picked or dropped onto the
window, and draws the browser as a modal window of the editor.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imgui_bundle import imgui

from vebuild.errors import VebuildError
from vebuild.project.video import is_video

from .layout import EditorPart
from .session import PHOTO_SUFFIXES
from .video_frames import VideoFrames

#: The browser window's title (ImGui's popup id).
BROWSER_TITLE = "Add photos"
#: Its size, window pixels (less where the window is smaller).
BROWSER_SIZE = (660.0, 500.0)
ERROR_COLOUR = (1.0, 0.45, 0.4, 1.0)


def is_photo_name(path: str | os.PathLike[str]) -> bool:
    """Whether the file's ending is one of the images vebuild reads."""
    return Path(path).suffix.lower() in PHOTO_SUFFIXES


def endings_text() -> str:
    plain = sorted(s for s in PHOTO_SUFFIXES if s in (".jpg", ".jpeg", ".png", ".tif", ".tiff"))
    return (", ".join(plain) + f", camera RAW ({len(PHOTO_SUFFIXES) - len(plain)} kinds: .nef, .cr2, .dng, …) and "
            "video files (.mp4, .mov, .avi, .mkv, …: a frame of them)")


@dataclass
class FileBrowser:
    """The folder shown, what it holds, and the files picked in it."""

    folder: Path
    have: set[Path] = field(default_factory=set)  # the project's photos (absolute): marked, not offered
    picked: set[str] = field(default_factory=set)
    error: str = ""
    typed: str = ""
    video: VideoFrames | None = None  # a video file opened to choose a frame of it
    _listing: tuple[list[str], list[str]] | None = None

    def __post_init__(self) -> None:
        self.folder = Path(os.path.abspath(self.folder))
        self.typed = str(self.folder)

    def listing(self) -> tuple[list[str], list[str]]:
        """The folder's sub-folders and image files, each sorted by name (case-insensitive)."""
        if self._listing is None:
            dirs: list[str] = []
            files: list[str] = []
            try:
                with os.scandir(self.folder) as it:
                    for e in it:
                        if e.name.startswith("."):
                            continue
                        try:
                            if e.is_dir():
                                dirs.append(e.name)
                            elif e.is_file() and (is_photo_name(e.name) or is_video(e.name)):
                                files.append(e.name)
                        except OSError:
                            continue
            except OSError as e:
                self.error = f"cannot list the folder {self.folder}: {e.strerror or e}"
            self._listing = (sorted(dirs, key=str.lower), sorted(files, key=str.lower))
        return self._listing

    def go(self, folder: str | os.PathLike[str]) -> bool:
        """Show another folder (a typed one: relative to the one shown); False, with the error
        said, when it is no folder."""
        target = Path(os.path.expanduser(str(folder)).strip())
        if not target.is_absolute():
            target = self.folder / target
        target = Path(os.path.abspath(target))
        if not target.is_dir():
            self.error = f"{target} is not a folder"
            self.typed = str(self.folder)
            return False
        self.folder, self.typed, self.error = target, str(target), ""
        self.picked.clear()
        self._listing = None
        return True

    def up(self) -> bool:
        return self.go(self.folder.parent)

    def enter(self, name: str) -> bool:
        return self.go(self.folder / name)

    def in_project(self, name: str) -> bool:
        return Path(os.path.abspath(self.folder / name)) in self.have

    def open_video(self, name: str, project_folder: str | os.PathLike[str]) -> bool:
        """Show the frames of a video file of the folder shown, to choose one; False, with the error
        said, where it cannot be read as a video."""
        try:
            self.video = VideoFrames.open(self.folder / name, project_folder)
        except VebuildError as e:
            self.error = str(e)
            return False
        self.error = ""
        return True

    def toggle(self, name: str) -> None:
        """Pick a file, or unpick it (a photo the project has already is not picked)."""
        if name in self.picked:
            self.picked.discard(name)
        elif name in self.listing()[1] and not self.in_project(name):
            self.picked.add(name)

    def pick_all(self) -> None:
        self.picked = {f for f in self.listing()[1] if not self.in_project(f) and not is_video(f)}

    def chosen(self) -> list[Path]:
        """The picked files, in name order."""
        return [self.folder / f for f in self.listing()[1] if f in self.picked]


def add_files(session: Any, paths: Iterable[str | os.PathLike[str]]) -> tuple[list[str], list[str]]:
    """Add each file as a photo through ``session.add_photo``; returns the ids added and, for each
    file that could not be, a sentence naming it and why (no image vebuild reads, outside the
    project's folder, unreadable, in the project already). A folder adds the image files directly
    inside it."""
    added: list[str] = []
    problems: list[str] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            inside = sorted(p for p in path.iterdir()
                            if p.is_file() and is_photo_name(p) and not p.name.startswith("."))
            if not inside:
                problems.append(f"{path}: a folder with no image files vebuild reads ({endings_text()})")
            more, bad = add_files(session, inside)
            added += more
            problems += bad
            continue
        if not path.exists():
            problems.append(f"{path}: no such file")
            continue
        if not is_photo_name(path):
            problems.append(f"{path.name}: not a photo vebuild reads (expected {endings_text()}); not added")
            continue
        have = {os.path.abspath(session.project.photo_path(p)): p["id"] for p in session.data["photos"]}
        if os.path.abspath(path) in have:
            problems.append(f"{path.name}: the project has it already, as photo '{have[os.path.abspath(path)]}'")
            continue
        try:
            added.append(session.add_photo(path))
        except VebuildError as e:
            problems.append(f"{path.name}: {e}")
    return added, problems


class PhotoBrowser(EditorPart):
    """The file browser and files dropped onto the window (a part of the Editor)."""

    browser: FileBrowser | None = None

    def open_browser(self) -> None:
        """The file browser, in the folder of the photo shown (else the project's folder)."""
        folder = Path(self.session.project.folder)
        if self.photo is not None:
            shown = Path(self.session.project.photo_path(self.session.photo(self.photo))).parent
            if shown.is_dir():
                folder = shown
        have = {Path(os.path.abspath(self.session.project.photo_path(p))) for p in self.session.data["photos"]}
        self.browser = FileBrowser(folder, have)
        self.help_open = False

    def on_drop(self, paths: list[str]) -> None:
        """Files dropped onto the window: each added as a photo (a folder: the images in it)."""
        if self._busy:
            return
        videos = [p for p in paths if is_video(p) and Path(p).is_file()]
        if videos:  # a video dropped: its frames shown in the browser, to choose one
            self.open_browser()
            assert self.browser is not None
            if self.browser.go(Path(videos[0]).parent):
                self.browser.open_video(Path(videos[0]).name, self.session.project.folder)
            paths = [p for p in paths if p not in videos]
            if not paths:
                return
        self.add_dropped_or_picked(paths)

    def add_dropped_or_picked(self, paths: list[Any], from_browser: bool = False) -> list[str]:
        """Add files as photos (the session's add_photo); the first added is shown; each file that
        cannot be added is named, with why, in the messages (and in the browser)."""
        added, problems = add_files(self.session, paths)
        for p in problems:
            self.say(p)
        if added:
            self.guard(self.set_photo, added[0])
        self.browser_problems = problems
        if self.browser is not None:
            if from_browser and not problems:
                self.browser = None
            else:
                self.browser.have |= {Path(os.path.abspath(self.session.project.photo_path(self.session.photo(a))))
                                      for a in added}
                self.browser.picked.clear()
                self.browser.error = "; ".join(problems)
        return added

    def _draw_browser(self) -> None:
        """The browser as a modal window over the editor (while ``browser`` is set)."""
        b = self.browser
        if b is None:
            return
        if not imgui.is_popup_open(BROWSER_TITLE):
            imgui.open_popup(BROWSER_TITLE)
        W, H = self.size()
        size = (min(BROWSER_SIZE[0], W - 40.0), min(BROWSER_SIZE[1], H - 40.0))
        imgui.set_next_window_pos((W / 2, H / 2), imgui.Cond_.always, (0.5, 0.5))
        imgui.set_next_window_size(size, imgui.Cond_.always)
        opened, keep = imgui.begin_popup_modal(BROWSER_TITLE, True, imgui.WindowFlags_.no_saved_settings
                                               | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_move)
        if not opened:
            self.browser = None
            return
        if not keep or self.browser is None:
            self.browser = None
            imgui.close_current_popup()
            imgui.end_popup()
            return
        pos = imgui.get_window_pos()
        self._rects["browser"] = (pos.x, pos.y, pos.x + size[0], pos.y + size[1])
        if b.video is not None:
            self._draw_frame_chooser(b, b.video, size)
            if self.browser is None:
                imgui.close_current_popup()
            imgui.end_popup()
            return
        if self.button("Up", tip="the folder that holds this one"):
            b.up()
        imgui.same_line()
        imgui.set_next_item_width(size[0] - 160)
        entered, b.typed = imgui.input_text("folder##browser", b.typed, imgui.InputTextFlags_.enter_returns_true)
        self.rect("browser folder")
        imgui.set_item_tooltip("type a folder and press Enter to show it")
        if entered:
            b.go(b.typed)
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled(f"photos lie in the project's folder ({self.session.project.folder}) or a folder inside "
                            f"it; shown: folders and {endings_text()}. Click files to pick them, then Add.")
        imgui.pop_text_wrap_pos()
        dirs, files = b.listing()
        list_h = max(80.0, size[1] - imgui.get_cursor_pos_y() - 110)
        imgui.begin_child("browser list", (0, list_h), imgui.ChildFlags_.borders)
        for d in dirs:
            if imgui.selectable(f"[folder] {d}/##dir:{d}", False)[0]:
                b.enter(d)
                break
            self.rect(f"browser:{d}/")
        else:
            for f in files:
                there = b.in_project(f)
                imgui.begin_disabled(there)
                video = "   (video: choose a frame)" if is_video(f) else ""
                if imgui.selectable(f"{f}{'   (in the project)' if there else video}##file:{f}", f in b.picked)[0]:
                    if video:
                        b.open_video(f, self.session.project.folder)
                    else:
                        b.toggle(f)
                imgui.end_disabled()
                self.rect(f"browser:{f}")
            if not dirs and not files and not b.error:
                imgui.text_disabled("no folders or photos here")
        imgui.end_child()
        if b.error:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(*ERROR_COLOUR), b.error)
            imgui.pop_text_wrap_pos()
        n = len(b.picked)
        imgui.begin_disabled(n == 0)
        if self.button(f"Add {n} photo{'s' if n != 1 else ''}###browser add",
                       tip="add the picked files to the project (their size, SHA-256 and EXIF recorded; the files are "
                           "not changed)"):
            self.add_dropped_or_picked(b.chosen(), from_browser=True)
        self.rect("browser add")
        imgui.end_disabled()
        imgui.same_line()
        if self.button("Pick all##browser", tip="pick every photo shown that the project lacks"):
            b.pick_all()
        imgui.same_line()
        if self.button("Cancel##browser", tip="close the browser (Esc)"):
            self.browser = None
        if self.browser is None:
            imgui.close_current_popup()
        imgui.end_popup()

    # -- a video's frames ---------------------------------------------------------------------------

    _video_tex: Any = None
    _video_tex_key: Any = None

    def _frame_texture(self, v: VideoFrames) -> Any:
        """The frame shown as a texture (made anew when the frame changes)."""
        key = (str(v.path), v.index)
        if self._video_tex_key != key:
            self._release_frame_texture()
            still = v.still()
            if still is None:
                return None
            h, w = still.rgb.shape[:2]
            self._video_tex = self.ctx.texture((w, h), 3, still.rgb.tobytes(), alignment=1)
            self._video_tex_key = key
        return self._video_tex

    def _release_frame_texture(self) -> None:
        if self._video_tex is not None:
            self.gui.forget_texture(self._video_tex)
            self._video_tex.release()
        self._video_tex = self._video_tex_key = None

    def step_video_frame(self, by: int) -> None:
        """, and . (or Left and Right) in the frame chooser: a frame back or on."""
        if self.browser is not None and self.browser.video is not None:
            self.browser.video.step(by)

    def _draw_frame_chooser(self, b: FileBrowser, v: VideoFrames, size: tuple[float, float]) -> None:
        imgui.text(v.label())
        self.rect("frame label")
        tex = self._frame_texture(v)
        avail_h = max(60.0, size[1] - imgui.get_cursor_pos_y() - 90)
        if tex is not None:
            w, h = tex.size
            scale = min((size[0] - 20) / w, avail_h / h)
            imgui.image(self.gui.texture_ref(tex), (w * scale, h * scale))
        else:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(*ERROR_COLOUR), v.error)
            imgui.pop_text_wrap_pos()
        if self.button("< frame##video back", tip="one frame back (, or Left)"):
            v.step(-1)
        self.rect("frame back")
        imgui.same_line()
        if self.button("frame >##video on", tip="one frame on (. or Right)"):
            v.step(1)
        self.rect("frame on")
        imgui.same_line()
        imgui.begin_disabled(tex is None)
        if self.button("Add this frame##video add", tip="add the frame shown as a photo: a lossless PNG beside the "
                       "video, with the video's SHA-256, the frame's number and time recorded"):
            try:
                added = v.add(self.session)
            except VebuildError as e:
                v.error = str(e)
                self.say(str(e))
            else:
                self._release_frame_texture()
                self.browser = None
                self.guard(self.set_photo, added)
        self.rect("frame add")
        imgui.end_disabled()
        imgui.same_line()
        if self.button("Back##video", tip="back to the folder (Esc)"):
            self._release_frame_texture()
            b.video = None
        if v.error and tex is not None:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(*ERROR_COLOUR), v.error)
            imgui.pop_text_wrap_pos()
