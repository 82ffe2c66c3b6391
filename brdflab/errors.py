"""The one error type that bad input raises, so the command line can turn it into one line."""

from __future__ import annotations

MAX_MESSAGE = 300  # characters of a message, past the file name


class BRDFLabError(Exception):
    """A problem with user input: a file, a value or an option.

    The message names the file (when there is one) and what is wrong; the command
    line prints it on one line and exits with status 2.
    """

    def __init__(self, message: str, path: object | None = None) -> None:
        self.path = None if path is None else str(path)
        message = " ".join(str(message).split())  # one line, whatever a library said
        if len(message) > MAX_MESSAGE:  # e.g. a list of a hostile file's 10⁶ attribute names
            message = message[:MAX_MESSAGE - 1] + "…"
        super().__init__(f"{self.path}: {message}" if self.path else message)
