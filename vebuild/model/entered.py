"""A node's ``hold`` list (FORMAT.md): parameters held exactly (a plain name, or an object with
σ 0), and dimensions entered from a measurement with its 1σ (``{"name", "sigma", "value"}``),
which the solve holds by a Gaussian prior (:mod:`.residuals`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


class HoldError(ValueError):
    """A bad entry of a ``hold`` list: ``at`` the JSON path below ``hold`` ("[2].sigma"), ``detail``
    what was expected."""

    def __init__(self, at: str, detail: str) -> None:
        super().__init__(detail)
        self.at, self.detail = at, detail


@dataclass(frozen=True)
class Entered:
    """A dimension entered from a measurement (a tape): an object of a node's ``hold`` list
    (FORMAT.md), with the measurement's 1σ and its value, both in file units (metres; degrees for
    an angle). σ > 0: the parameter is solved, held by a Gaussian prior at ``value`` with that 1σ
    (:mod:`.residuals`); σ = 0: held exactly, as a plain name is. ``value`` None: the parameter's
    value as the file gives it (:func:`model_from_dict` fills it in, so that the entered value
    stays when a solve moves the parameter)."""

    name: str
    sigma: float
    value: float | None = None

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"name": self.name, "sigma": self.sigma}
        if self.value is not None:
            d["value"] = self.value
        return d


def _number(v: Any) -> bool:
    """A finite JSON number (not a boolean)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and bool(np.isfinite(v))


def hold_list(items: Any, known: tuple[str, ...]) -> tuple[tuple[str, ...], tuple[Entered, ...]]:
    """A node's ``hold`` list: (the names held exactly, the entries given as objects), checked."""
    if not isinstance(items, list | tuple):
        raise HoldError("", f"expected a list of parameter names or "
                     f"{{\"name\", \"sigma\"}} objects, got {items!r}")
    hold: list[str] = []
    entered: list[Entered] = []
    seen: set[str] = set()
    for k, h in enumerate(items):
        at = f"[{k}]"
        if isinstance(h, dict):
            extra = sorted(set(h) - {"name", "sigma", "value"})
            if extra:
                raise HoldError(f"{at}.{extra[0]}", f"an entered value has the fields name, sigma and "
                             f"value (optional); got {extra[0]!r}")
            name, sigma, value = h.get("name"), h["sigma"] if "sigma" in h else None, h.get("value")
            if not isinstance(name, str):
                raise HoldError(f"{at}.name", f"expected the name of a parameter of this node (it has: "
                             f"{', '.join(known)}), got {name!r}")
            if not isinstance(sigma, int | float) or not (_number(sigma) and sigma >= 0):
                raise HoldError(f"{at}.sigma", f"expected the 1σ of the measurement entered for "
                             f"'{name}' as a number ≥ 0 (metres, or degrees for an angle), got {sigma!r}")
            if value is not None and not (isinstance(value, int | float) and _number(value)):
                raise HoldError(f"{at}.value", f"expected the value entered for '{name}' as a "
                             f"finite number (metres, or degrees for an angle), got {value!r}")
            e = Entered(name, float(sigma), None if value is None else float(value))  # (numbers: checked)
            entered.append(e)
            at_name = f"{at}.name"
        elif isinstance(h, str):
            name, at_name = h, at
        else:
            raise HoldError(at, f"expected a parameter name or an object {{\"name\", \"sigma\"}}, "
                         f"got {h!r}")
        if name not in known:
            raise HoldError(at_name, f"'{name}' is not a parameter of this node (it has: "
                         f"{', '.join(known)})")
        if name in seen:
            raise HoldError(at_name, f"'{name}' is held twice: expected each parameter once in the list")
        seen.add(name)
        if isinstance(h, str) or entered[-1].sigma == 0:
            hold.append(name)
    return tuple(hold), tuple(entered)
