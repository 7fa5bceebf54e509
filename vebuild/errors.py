"""Errors a user can act on.

Every error raised for bad input is a :class:`VebuildError`: the command line prints its message
(no traceback) and exits with status 2. Messages say where (file, JSON path, photo, axis), what was
expected and what was found.
"""

from __future__ import annotations


class VebuildError(Exception):
    """Base class of every error caused by the user's input rather than by a bug."""


class ProjectError(VebuildError):
    """The project file or a file it names is malformed, missing or changed.

    Parameters
    ----------
    file : the file concerned (project file or photo).
    where : a JSON path inside the project file such as ``$.photos[2].width`` ('' for the file).
    message : what was expected and what was found.
    """

    def __init__(self, file: object, where: str, message: str, words: str = "") -> None:
        self.file = str(file)
        self.where = where
        self.detail = message
        self.words = words
        if words:
            loc = f"{self.file}: {words}, at {where}: "
        else:
            loc = f"{self.file}: {where}: " if where else f"{self.file}: "
        super().__init__(loc + message)

    def named(self, words: str) -> ProjectError:
        """The same error with the place also said in words (``photo 'door', field "width"``)."""
        if not words or self.words:
            return self
        e = ProjectError(self.file, self.where, self.detail, words)
        e.__traceback__ = self.__traceback__
        return e


class UndeterminedError(VebuildError):
    """The observations leave parts of the model undetermined: ``names`` lists them (``node.param``,
    the solver's order); the message says what would determine each."""

    def __init__(self, message: str, names: list[str]) -> None:
        self.names = list(names)
        super().__init__(message)


class CalibrationError(VebuildError):
    """The marks cannot determine a camera; the message says which marks to add or fix.

    ``photo`` names the photo concerned, or is None when the problem is the project's as a whole
    (no reference distance, say).
    """

    def __init__(self, photo: str | None, message: str) -> None:
        self.photo = photo
        self.detail = message
        super().__init__(f"photo '{photo}': {message}" if photo else message)
