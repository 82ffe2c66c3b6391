"""The command line's argument parsing: help that shows defaults and examples, one-line
errors for bad options, and option types that refuse out-of-range values up front.

Kept free of NumPy and every heavy library, so that `brdflab --help` starts at once.
"""

from __future__ import annotations

import argparse
import math


class UsageError(Exception):
    """A bad option or argument: `main` prints it on one line and exits with status 2."""


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Shows each option's default (unless it is None or a plain flag) and keeps the
    examples in the epilog as written."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if ("%(default)" in text or default is None or default is False or default == argparse.SUPPRESS
                or not (action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE))):
            return text
        return f"{text} (default: %(default)s)" if text else "(default: %(default)s)"


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line (`brdflab render: argument --samples: …`)
    raised as UsageError, not the usage block and SystemExit that argparse prints."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        raise UsageError(f"{self.prog}: {' '.join(message.split())} (see `{self.prog} --help`)")


def int_in(low: int, high: int, what: str = "an integer", name: str = ""):
    """An argparse type: an integer in [low, high] (`name` leads the out-of-range message)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} (expected {low}..{high})") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{name} {value} is outside {low}..{high}".strip())
        return value
    parse.__name__ = what
    return parse


def finite_float(text: str) -> float:
    """An argparse type: a finite number (no nan or inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


MAX_IMAGE_PIXELS = 4096 * 4096  # a render holds ~120 bytes per pixel (2 GB at this size)


def image_size(text: str) -> tuple[int, int]:
    """An argparse type: `W,H`, each side 1..8192 pixels, at most MAX_IMAGE_PIXELS in all
    (8192 × 8192 needed 8 GB and ended in a MemoryError)."""
    parts = text.split(",")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected W,H (two whole numbers of pixels)") from None
    if not (1 <= width <= 8192 and 1 <= height <= 8192):
        raise argparse.ArgumentTypeError(f"{text!r}: each side must be 1..8192 pixels")
    if width * height > MAX_IMAGE_PIXELS:
        raise argparse.ArgumentTypeError(f"{text!r}: {width * height:,} pixels; the renderer draws at most "
                                         f"{MAX_IMAGE_PIXELS:,} (e.g. 4096,4096 or 8192,2048)")
    return width, height


def material_path(text: str) -> str:
    """An argparse type for a material argument: a path, or `example:NAME` for a shipped example."""
    from brdflab.errors import BRDFLabError
    from brdflab.io.resources import resolve_material

    try:
        return str(resolve_material(text))
    except BRDFLabError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def sh_table(text: str):
    """An argparse type for `--sh-table`: 'auto', or SIZExLOG2 as a TableSetting (imported only
    when the option is given, so that --help stays light)."""
    if text.strip().lower() == "auto":
        return "auto"
    from brdflab.errors import BRDFLabError
    from brdflab.lighting.sh_tables import parse_setting

    try:
        return parse_setting(text)
    except BRDFLabError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
