"""Argument checks of the command line: one clear line and exit status 2 on bad input."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from parcover_env.errors import OutputError

__all__ = ["OneLineParser", "non_negative_int", "positive_int", "int_at_most", "check_writable_file",
           "check_writable_dir"]


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line (no usage block): ``prog: error: message``."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")
        sys.exit(2)


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def non_negative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds)."""
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1 (counts, step limits)."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def int_at_most(high: int):
    """argparse type: an integer in [1, ``high``] (a count whose work or memory grows with it)."""

    def parse(text: str) -> int:
        value = positive_int(text)
        if value > high:
            raise argparse.ArgumentTypeError(f"must be <= {high}, got {value}")
        return value

    parse.__name__ = f"integer in [1, {high}]"
    return parse


def check_writable_file(path: str | os.PathLike, option: str) -> None:
    """Raise OutputError unless ``path`` can be created or overwritten (checked before any work)."""
    p = Path(path)
    if p.is_dir():
        raise OutputError(f"{option}: {p} is a directory, expected a file name")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError(f"{option}: cannot write {p}: directory {parent} does not exist")
    if (p.exists() and not os.access(p, os.W_OK)) or not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{option}: cannot write {p}: permission denied")


def check_writable_dir(path: str | os.PathLike, option: str) -> None:
    """Create directory ``path`` (and parents) or raise OutputError naming it."""
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{option}: cannot create directory {p}: {exc.strerror or exc}") from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise OutputError(f"{option}: cannot write into directory {p}: permission denied")


def write_image(path: str | os.PathLike, rgb, option: str) -> None:
    """Write an RGB image (PNG or any format OpenCV knows by the extension) or raise OutputError."""
    import cv2

    try:
        ok = cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"{option}: cannot write {path} (check the directory and the file extension, e.g. .png)")
