"""What the package's command-line tools share: an argparse parser whose errors are one line."""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a bad argument ends with one line `<prog>: <message>` on stderr and exit
    status 2 (no usage block)."""

    def error(self, message: str) -> NoReturn:
        print(f'{self.prog}: {message} (see --help)', file=sys.stderr)
        raise SystemExit(2)


def fail(prog: str, message: str) -> int:
    """Print the one-line error and return exit status 2."""
    print(f'{prog}: {" ".join(str(message).split())}', file=sys.stderr)
    return 2
