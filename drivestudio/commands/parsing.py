"""The command-line parser every drivestudio entry point uses: a bad option is one line on stderr and exit status 2,
not a usage dump."""
from __future__ import annotations

import argparse


class Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, not a usage dump
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")
