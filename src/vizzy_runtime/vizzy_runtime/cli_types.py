"""argparse value types and the one-line error of the `vizzy` command and its verb modules
(cli.py, cli_topic.py, ...). Imports nothing heavy: `vizzy` parses its arguments before it loads
DDS or NumPy."""

from __future__ import annotations

import argparse
import math
import sys


def die(message: str, code: int = 2) -> int:
    """Print `vizzy: <message>` on stderr; the exit code to return."""
    print(f'vizzy: {message}', file=sys.stderr)
    return code


def _seconds(text: str, *, zero: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number of seconds') from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not zero):
        raise argparse.ArgumentTypeError(
            f'{text!r}: expected a {"non-negative" if zero else "positive"} number of seconds')
    return value


def positive_seconds(text: str) -> float:
    """argparse type: a finite number of seconds > 0."""
    return _seconds(text, zero=False)


def nonnegative_seconds(text: str) -> float:
    """argparse type: a finite number of seconds >= 0."""
    return _seconds(text, zero=True)


def positive_number(text: str) -> float:
    """argparse type: a finite number > 0 (a playback rate, a frequency)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r}: expected a positive number')
    return value


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0 (a count)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not an integer') from None
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text!r}: expected an integer >= 0')
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    value = nonnegative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError(f'{text!r}: expected an integer >= 1')
    return value


def port_number(text: str) -> int:
    """argparse type: a TCP port, 0..65535 (0: any free one)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a port number') from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f'{text!r}: a port is 0..65535 (0: any free one)')
    return value
