"""The command line's argument parser: errors in one line, exit 2."""

from __future__ import annotations

import argparse
import re
from typing import NoReturn

_INVALID_VALUE = re.compile(r"argument (\S+?)(?:/\S+)?: invalid (int|float) value: (.*)")
_INVALID_CHOICE = re.compile(
    r"argument (\S+?)(?:/\S+)?: invalid choice: '(.*)' \(choose from (.*)\)"
)


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line naming the option and the problem
    (``--horizon 3.5: expected a whole number``), exit 2, instead of the usage."""

    def error(self, message: str) -> NoReturn:
        m = _INVALID_VALUE.fullmatch(message)
        if m is not None:
            what = "a whole number" if m.group(2) == "int" else "a number"
            message = f"{m.group(1)} {m.group(3)}: expected {what}"
        elif message.startswith("unrecognized arguments: "):
            message += self._did_you_mean(message.split(": ", 1)[1].split())
        elif (c := _INVALID_CHOICE.fullmatch(message)) is not None:
            import difflib

            choices = [x.strip(" '") for x in c.group(3).split(",")]
            by_lower = {x.lower(): x for x in choices}  # EKF for ekf: case alone is close
            close = [
                by_lower[x]
                for x in difflib.get_close_matches(c.group(2).lower(), by_lower, n=1, cutoff=0.6)
            ]
            what = (
                f"{c.group(2)!r} is not a command"
                if c.group(1) == "COMMAND"
                else (f"{c.group(1)} {c.group(2)!r}")
            )
            message = f"{what}: expected one of {', '.join(choices)}"
            if close:
                message += f"; did you mean {close[0]}?"
        self.exit(2, f"{self.prog}: error: {message} ({self.prog} --help lists the options)\n")

    def _did_you_mean(self, given: list[str]) -> str:
        """``; did you mean --length?`` for a misspelt option among ``given``, else ``""``."""
        import difflib

        known = [o for a in self._actions for o in a.option_strings if o.startswith("--")]
        for word in given:
            if word.startswith("--"):
                close = difflib.get_close_matches(word.split("=", 1)[0], known, n=1, cutoff=0.75)
                if close:
                    return f"; did you mean {close[0]}?"
        return ""
