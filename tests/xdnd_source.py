"""Files dropped onto a window the way a file manager drops them: the source side of X's drag and
drop protocol (XDND, version 5, freedesktop.org), over its own connection to the X server.

xdotool moves and clicks but has no drag source; this one announces ``text/uri-list`` to the
target window (XdndEnter), moves over it (XdndPosition), waits for its XdndStatus, drops
(XdndDrop), answers the target's request for the selection with the files' URIs (SelectionRequest,
SelectionNotify), and waits for XdndFinished. The window keeps drawing frames meanwhile (``pump``),
so that it reads its events.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from urllib.parse import quote

from Xlib import X, display, protocol

XDND_VERSION = 5


def drop_files(window_id: int, xy: tuple[int, int], files: Sequence[Path], pump: Callable[[], None],
               timeout_s: float = 20.0) -> dict[str, bool]:
    """Drop ``files`` onto the X window ``window_id`` at window pixel ``xy``; returns what the
    target answered: ``accepted`` (its XdndStatus) and ``finished`` (its XdndFinished, the drop
    taken)."""
    dpy = display.Display()
    try:
        atom = dpy.intern_atom
        root = dpy.screen().root
        source = root.create_window(0, 0, 1, 1, 0, X.CopyFromParent)
        target = dpy.create_resource_object("window", int(window_id))
        uri_list = atom("text/uri-list")
        selection = atom("XdndSelection")
        source.set_selection_owner(selection, X.CurrentTime)
        payload = "".join(f"file://{quote(str(Path(f).resolve()))}\r\n" for f in files).encode()

        def send(kind: str, data: list[int]) -> None:
            ev = protocol.event.ClientMessage(window=target, client_type=atom(kind), data=(32, data))
            target.send_event(ev, event_mask=0)
            dpy.flush()

        at = target.translate_coords(root, 0, 0)  # the window's origin, in root coordinates
        rx, ry = xy[0] - at.x, xy[1] - at.y
        send("XdndEnter", [source.id, XDND_VERSION << 24, uri_list, 0, 0])
        send("XdndPosition", [source.id, 0, (rx << 16) | ry, X.CurrentTime, atom("XdndActionCopy")])
        state = {"accepted": False, "finished": False, "status": False}
        dropped = False
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and not state["finished"]:
            pump()
            while dpy.pending_events():
                ev = dpy.next_event()
                if ev.type == X.ClientMessage and ev.client_type == atom("XdndStatus"):
                    state["status"] = True
                    state["accepted"] = bool(ev.data[1][1] & 1)
                elif ev.type == X.ClientMessage and ev.client_type == atom("XdndFinished"):
                    state["finished"] = True
                elif ev.type == X.SelectionRequest and ev.selection == selection:
                    ev.requestor.change_property(ev.property, ev.target, 8, payload)
                    notify = protocol.event.SelectionNotify(time=ev.time, requestor=ev.requestor,
                                                            selection=ev.selection, target=ev.target,
                                                            property=ev.property)
                    ev.requestor.send_event(notify)
                    dpy.flush()
            if state["status"] and not dropped:
                if not state["accepted"]:
                    break
                send("XdndDrop", [source.id, 0, X.CurrentTime, 0, 0])
                dropped = True
        return {"accepted": state["accepted"], "finished": state["finished"]}
    finally:
        dpy.close()
