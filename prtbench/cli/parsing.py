"""The command line's parser: every mistake made on it is one line, exit status 2.

argparse answers a bad argument with its usage block (3 to 6 lines) and then the message;
the README promises one line, ``prtbench: error: …``, naming the bad value and what is
accepted, like every other user mistake (:class:`prtbench.api.errors.PrtbenchError`). The
:class:`Parser` here keeps argparse and changes what it says and reads:

* every error is one line (no usage block; ``--help`` still prints it), with the choices
  of a bad choice and a did-you-mean for a bad choice or an unknown option;
* an option whose value is a string refuses an empty one (``--light ''`` would otherwise
  fall back to the default light in silence), unless the empty string is its default;
* a value that starts with ``-`` but is no option (``--res -64x48``, ``--light -x``) is the
  option's value, so it is checked, and refused, like any other value;
* :func:`integer` reads whole numbers strictly (``--views 1.5``, ``1e3``, ``abc``, ``''``).
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

#: How an argparse message names its argument: ``argument --views: invalid ...``.
_ARGUMENT = re.compile(r"^argument (?P<name>[^:]+): (?P<message>.*)$", re.S)
#: How argparse's message about missing arguments starts.
_REQUIRED = "the following arguments are required: "


def one_line(text: str) -> str:
    """``text`` with its line breaks and runs of blanks made single spaces."""
    return " ".join(text.split())


def integer(accepted: str) -> Callable[[str], int]:
    """An argparse ``type`` reading a whole number, refusing ``1.5``, ``1e3``, ``nan``, ``''``.

    Parameters
    ----------
    accepted : str
        What the option accepts, for the message (``"a whole number of views, 1 or more"``);
        ranges that depend on other options (a scene's view count) are checked later.
    """

    def parse(text: str) -> int:
        if not re.fullmatch(r"\s*[+-]?\d+\s*", text):
            raise argparse.ArgumentTypeError(f"'{text}'; accepted: {accepted}")
        return int(text)

    parse.__name__ = "integer"
    return parse


def _unknown_name(kind: str, name: str, accepted: Sequence[str]) -> str:
    """``unknown option '--resutls'; did you mean '--results'? accepted: ...``."""
    close = difflib.get_close_matches(name, accepted, n=1, cutoff=0.6)
    hint = f"; did you mean '{close[0]}'?" if close else ";"
    return f"unknown {kind} '{name}'{hint} accepted: {', '.join(accepted) or '(none)'}"


def _non_empty(convert: Callable[[str], Any], accepted: str) -> Callable[[str], Any]:
    """``convert`` that first refuses the empty (or blank) string."""

    def parse(text: str) -> Any:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"'{text}'; accepted: {accepted}")
        return convert(text)

    parse.__name__ = getattr(convert, "__name__", "value")
    return parse


class Parser(argparse.ArgumentParser):
    """argparse's parser with one-line errors (see the module docstring).

    Subparsers are made of the same class (argparse's default), so every subcommand, and
    a subcommand's own subcommands (``scene info``, ``cache prune``), behave alike. Errors
    print one line on stderr and raise ``SystemExit(2)``, as argparse does.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # Before argparse's __init__, which adds -h/--help through add_argument.
        self._value_options: set[str] = set()  # options taking one value
        self._options: list[str] = []  # every option string
        self._subcommands: argparse.Action | None = None
        super().__init__(*args, **kwargs)

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        takes_text = (kwargs.get("action") in (None, "store", "append")
                      and kwargs.get("nargs") is None and kwargs.get("type") in (None, str)
                      and kwargs.get("choices") is None)  # a choice names what is accepted
        if takes_text and kwargs.get("default") != "":
            accepted = one_line(kwargs.get("help") or "a non-empty value")
            kwargs["type"] = _non_empty(str, accepted)
        action = super().add_argument(*args, **kwargs)
        if action.option_strings and action.nargs is None:
            self._value_options.update(action.option_strings)
        self._options.extend(action.option_strings)
        return action

    def add_subparsers(self, **kwargs: Any):
        self._subcommands = super().add_subparsers(**kwargs)
        return self._subcommands

    def parse_known_args(self, args: Sequence[str] | None = None,
                         namespace: argparse.Namespace | None = None):
        args = list(sys.argv[1:] if args is None else args)
        namespace, extras = super().parse_known_args(self._join_dashed_values(args), namespace)
        if extras:  # this parser's own leftovers: a subcommand's never reach its parent
            self._unknown(extras[0])
        return namespace, extras

    def _join_dashed_values(self, args: list[str]) -> list[str]:
        """``--res -64x48`` as ``--res=-64x48``: argparse would take ``-64x48`` for an option.

        Only a word after an option of this parser that takes one value, and only a word
        with a single leading dash that is none of this parser's options (``--res -h`` and
        ``--out --quiet`` are still missing values)."""
        options, joined, index = self._value_options, [], 0
        while index < len(args):
            word = args[index]
            following = args[index + 1] if index + 1 < len(args) else None
            if word == "--":
                joined += args[index:]
                break
            if (word in options and following is not None and following.startswith("-")
                    and not following.startswith("--") and len(following) > 1
                    and following.split("=", 1)[0] not in self._options):
                joined.append(f"{word}={following}")
                index += 2
                continue
            joined.append(word)
            index += 1
        return joined

    def _command(self) -> str:
        """``run`` for ``prtbench run``, ``scene info`` for ``prtbench scene info``."""
        return self.prog.partition(" ")[2]

    def _see_help(self) -> str:
        command = self._command()
        return f"see `prtbench {command} --help`" if command else "see `prtbench --help`"

    def _unknown(self, word: str) -> NoReturn:
        command = self._command()
        where = f"{command}: " if command else ""
        options = sorted({o for o in self._options if o.startswith("--")} - {"--help"})
        if word.startswith("-"):
            name = word.split("=", 1)[0]
            self.error(f"{where}{_unknown_name('option', name, options)}", raw=True)
        self.error(f"{where}unexpected argument '{word}'; {self._see_help()}", raw=True)

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        # argparse's "invalid choice: 'x' (choose from ...)", with a did-you-mean (argparse's
        # own hook for the check, private but unchanged in its signature since Python 2.7).
        if action.choices is not None and value not in action.choices:
            kind = (action.metavar or action.dest or "value").lower().replace("_", " ")
            raise argparse.ArgumentError(None, _unknown_name(kind, value, list(action.choices)))

    def error(self, message: str, *, raw: bool = False) -> NoReturn:
        """Print ``prtbench: error: <message>`` (one line) and exit with status 2."""
        if not raw:
            message = self._rephrase(message)
        print(f"prtbench: error: {one_line(message)}", file=sys.stderr)
        raise SystemExit(2)

    def _rephrase(self, message: str) -> str:
        """argparse's message in the CLI's words (the option first, what is accepted)."""
        command, see = self._command(), self._see_help()
        if message.startswith(_REQUIRED):
            missing = message[len(_REQUIRED):]
            where = f"{command}: " if command else ""
            sub = self._subcommands
            if sub is not None and missing in (sub.metavar, sub.dest):
                return f"{where}missing {missing}; accepted: {', '.join(sub.choices)}"
            return f"{where}missing {missing}; {see}"
        found = _ARGUMENT.match(message)
        if found is None:  # an unknown choice says what is accepted; the rest point to --help
            where = f"{command}: " if command else ""
            return f"{where}{message}" + ("" if message.startswith("unknown ") else f"; {see}")
        name, text = found["name"], found["message"]
        if text.startswith("'"):  # a value the option's type refused: it says what is accepted
            return f"{name} {text}"
        return f"{name}: {text}; {see}"
