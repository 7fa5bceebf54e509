"""The same figures on any machine: linear algebra on a fixed number of threads.

A multi-threaded BLAS (OpenBLAS, as numpy's and scipy's wheels bundle it) splits a product or a
factorisation differently for each number of threads, and so adds its partial sums in another
order: the solved model and cameras then differ in the last digits from one machine to another
(by up to 1e-5 on the example), and everything made from them (textures, renders, the .glb, the
report's hashes) differs in its bytes. A second examiner must get the same bytes, so every
least-squares solve runs with one BLAS/OpenMP thread, whatever the machine has. Its matrices are
small (the example's re-calibration: 320 × 111), where a second thread saves well under a
millisecond a solve, and on a busy machine OpenBLAS's waiting threads cost far more than that.

What this does not fix: OpenBLAS chooses its kernels for the CPU (``OPENBLAS_CORETYPE``), and a
CPU given other kernels (AVX2 rather than AVX-512, or another architecture) adds in another order
even on one thread. The same bytes need the same kernels, as well as the same numpy, scipy and
Mesa.

:func:`fixed_threads` is the one place that does it: a context manager and a decorator, put on
the solvers' entry points (so the editor's drags, which call them directly, are covered too)
and around every command of the command line. It nests, and it is safe when solves run in more
than one thread at once: the first to enter sets one thread, the last to leave restores what was
there before. A library loaded while it is in force (scipy's, imported at a solver's first use so
that ``vebuild check`` never loads it: docs/start-up.md) starts with one thread, from the
environment variables it reads as it loads, which are set for as long. The thread counts of the
BLAS and OpenMP libraries are process-wide settings, so a caller's own numpy work in another
thread also runs single-threaded while a solve is under way.
"""

from __future__ import annotations

import functools
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

#: The number of BLAS and OpenMP threads every solve runs with.
THREADS = 1

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
_depth = 0
_limiter: Any = None
_controller: Any = None
_modules_seen = 0
_environment: dict[str, str | None] = {}

#: The environment variables from which a BLAS or OpenMP library takes its thread count as it loads.
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def _threadpools() -> Any:
    """threadpoolctl's controller over the BLAS and OpenMP libraries loaded (numpy's and scipy's
    wheels bring one each), made again when modules were imported since, which may have brought
    another (OpenCV's wheel bundles an OpenBLAS of its own). One loaded later takes its count from
    :data:`THREAD_VARIABLES`."""
    global _controller, _modules_seen
    if _controller is None or len(sys.modules) != _modules_seen:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
        _modules_seen = len(sys.modules)
    return _controller


@contextmanager
def fixed_threads() -> Iterator[None]:
    """Run the body with :data:`THREADS` BLAS and OpenMP threads; restore the count afterwards."""
    global _depth, _limiter
    with _lock:
        if _depth == 0:
            _environment.update({v: os.environ.get(v) for v in THREAD_VARIABLES})
            os.environ.update({v: str(THREADS) for v in THREAD_VARIABLES})
            # Before numpy is imported no BLAS is loaded: the variables set its count as it loads
            # (and threadpoolctl, 20 ms of a command's start-up, is not needed).
            _limiter = _threadpools().limit(limits=THREADS) if "numpy" in sys.modules else None
            if _limiter is not None:
                _release_openblas()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                if _limiter is not None:
                    _limiter.restore_original_limits()
                    _limiter = None
                    _release_openblas()
                for v, value in _environment.items():
                    if value is None:
                        os.environ.pop(v, None)
                    else:
                        os.environ[v] = value
                _environment.clear()


def _release_openblas() -> None:
    """Let the next thread that enters set OpenBLAS's count. threadpoolctl 3.8 lets only the thread
    that first set a pthreads OpenBLAS's count set it again (others are silently ignored) until
    that thread clears it; earlier versions have no such rule. Here the lock above already keeps
    threads from fighting, and the thread that restores the count need not be the one that set it."""
    import threadpoolctl

    clear = getattr(getattr(threadpoolctl, "OpenBLASController", None), "clear_controlling_thread", None)
    if clear is not None:
        clear(force=True)


def deterministic(fn: F) -> F:
    """Decorate a solver's entry point: its body runs under :func:`fixed_threads`."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with fixed_threads():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


#: glibc's ``mallopt`` parameter that fills every block ``malloc`` hands out (and every one freed).
_M_PERTURB = -6


@contextmanager
def filled_allocations(byte: int = 0x5A) -> Iterator[None]:
    """Every heap block allocated while this is in force comes filled with the same bytes, not with
    what the allocator left there (glibc's ``M_PERTURB``; elsewhere it does nothing).

    For the H.264 encoder (x264 through FFmpeg), whose output for the same pictures depended on
    what was in memory before: a 96 × 64 walk-through of the example room gave 4 different files
    in 10 runs in one process, and two in every run or two once blocks freed were refilled with
    random bytes between frames; with the blocks filled, 10 of 10 were the same. It reads memory
    it never wrote (frames of a width whose rows do not fill its vector blocks); which bytes
    are there changes its decisions, so they must not depend on what the process did before.
    A process-wide setting: other threads' allocations are filled too while it holds (a memset
    each; nothing else changes). Set back to off when the block ends.
    """
    mallopt = _mallopt()
    if mallopt is not None:
        mallopt(_M_PERTURB, byte)
    try:
        yield
    finally:
        if mallopt is not None:
            mallopt(_M_PERTURB, 0)


def _mallopt() -> Callable[[int, int], int] | None:
    import ctypes

    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt)
        return None
