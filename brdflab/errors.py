"""The one error type that bad input raises, so the command line can turn it into one line."""

from __future__ import annotations

import os

MAX_MESSAGE = 300  # characters of a message, past the file name
MAX_PATH_SHOWN = 200  # characters of the file name itself (its middle is elided)


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
        super().__init__(f"{shown_path(self.path)}: {message}" if self.path else message)


def shown_path(path: object) -> str:
    """A file name as one printable line: bytes that are not UTF-8 as \\xNN, control
    characters (a newline in the name) as escapes and the middle of an over-long name elided,
    so an error stays one short line that any terminal or log can hold."""
    text = str(path)
    try:
        text = os.fsencode(text).decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a lone surrogate that was not an undecodable byte
        text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return text if len(text) <= MAX_PATH_SHOWN else f"{text[:MAX_PATH_SHOWN - 61]}…{text[-60:]}"


def is_text_name(path: object) -> bool:
    """Whether a file name is UTF-8 text. One that is not reaches Python as lone surrogates
    (PEP 383): it names its file, but no XML, CSV or JSON record can hold it as it is."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True
