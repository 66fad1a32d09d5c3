"""Every ``fliss`` command example of the README, of ``docs/*.md`` and of the ``--help`` texts, as
argument lists (the tests: ``tests/project/test_doc_examples.py``).

Where examples are found:

* in a fenced code block, a line that starts with ``fliss``, ``$ fliss`` or ``.venv/bin/fliss``
  (a ``\\`` at its end continues it on the next line; ``;`` separates two commands; ``#`` starts a
  comment);
* in prose and tables, an inline code span that starts so (it may run over two lines; ``\\|`` in a
  table is ``|``);
* in ``fliss CMD --help``: a code span in a description or help string, and the values an option's
  help gives as examples: ``(e.g. 0ns 200ns)``, ``(for example 1e-4)``, ``(80MHz, 79.5e6, ...)``,
  ``(1e6 for the keyed claim)``, ``(first timestamp: 100ns, or 2000codes)``, each value a number
  with an optional unit, a ``0x`` number or ``ROWSxCOLUMNS``; each becomes
  ``fliss CMD --option VALUE``.

How an example reads (a synopsis as much as a command line):

* ``[...]`` is optional and is given; ``a | b`` inside brackets, and ``a|b`` in one word, are
  alternatives: the example gives as many argument lists as its widest choice has alternatives,
  the ``i``-th taking the ``i``-th alternative of each choice (so every alternative is used once);
* ``...`` stands for options left out; it is dropped;
* placeholders (``P``, ``N``, ``FILE``, ``/dev/pts/N``...) take a value from :data:`PLACEHOLDERS`;
* in a fenced block, a ``config`` or ``capture`` example that names no port (``fliss capture
  ... -o FILE``) uses the port of the example above it that names one;
* a span that ends in an option that takes a value, with no value (``fliss config --iv``), names
  that option: :attr:`Example.mention`.
"""

import argparse
import re
import shlex
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import count
from pathlib import Path
from typing import List, Optional, Tuple

from fliss.host.cli import build_parser


ROOT = Path(__file__).resolve().parents[2]
DOCS = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))

#: The values given to the placeholders of the examples. Ports stay names of the docs' own
#: (a test maps each to a model board): ``/dev/pts/M`` is the demo's second board, the line scene.
PLACEHOLDERS = {
    "P": "/dev/pts/N",
    "N": "2",                          # counts: --workers, --acquisitions, --reset-after, --line-seed
    "M": "2.5",                        # metres: --object-m
    "R": "0.01",                       # rates per byte: --line-drop, --line-duplicate, --line-stall
    "K": "80000000000000000000",       # a key: the published Trivium test vector's
    "IV": "0",
    "W": "6",
    "SPEC": "examples/sweep-quick.toml",
    "DIR": "out",
    "FILE": "capture.h5",
    "CAPTURE": "raw.h5",               # a raw capture: every format takes one
    "OUT": "export.out",
    "tcp://HOST:PORT": "tcp://127.0.0.1:8786",
}

#: The commands that set up a board and write the files that the next examples of a session
#: read; they run before each later example of their fenced block.
SESSION_COMMANDS = ("config", "capture")
#: The commands that use a board or capture files: they run after those of their session.
SESSION_READERS = ("config", "capture", "analyze", "plot", "export")

_PREFIX = re.compile(r"^(?:\$ )?(?:\.venv/bin/)?fliss(?= |$)")
#: A value in a help text: a number with an optional unit, a 0x number, ROWSxCOLUMNS.
_VALUE = re.compile(r"-?\d+(?:\.\d+)?(?:e-?\d+)?(?:ps|ns|us|µs|ms|s|Hz|kHz|MHz|GHz|cycles|codes|M|k)?"
                    r"|0x[0-9a-fA-F]+|\d+x\d+")


@dataclass
class Example:
    """One command example: where it is, as written, and the argument lists it stands for.

    ``argvs`` are the argument lists after ``fliss`` (one per alternative); ``before`` are the
    argument lists of the examples above it in the same fenced block, which set up the board and
    the files it uses (a fenced block reads as a session); ``mention`` is the option a span names
    without a value, else None.
    """
    where: str
    text: str
    argvs: List[List[str]]
    before: List[List[str]] = field(default_factory=list)
    mention: Optional[str] = None

    @property
    def command(self) -> Optional[str]:
        return self.argvs[0][0] if self.argvs[0] else None


@lru_cache(maxsize=None)
def subparsers():
    """The parser of each sub-command, by name."""
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def positionals(command, tokens):
    """The positional arguments among ``tokens``, the arguments of ``fliss command``."""
    options = subparsers()[command]._option_string_actions
    found, values = [], 0        # values the option before still takes (None: any number)
    for token in tokens:
        if token in options:
            nargs = options[token].nargs
            values = {None: 1, "?": 1, "*": None, "+": None}.get(nargs, nargs)
        elif values is None or values > 0:
            values = None if values is None else values - 1
        else:
            found.append(token)
    return found


def _alternatives(tokens):
    """The argument lists of a synopsis's tokens (brackets, ``|``), as the module says."""
    # A tree: a sequence holds words and choices; a choice holds sequences.
    stack = [[]]
    choices = [None]
    for token in tokens:
        opened = 0
        while token.startswith("["):
            token = token[1:]
            opened += 1
        closed = 0
        while token.endswith("]"):
            token = token[:-1]
            closed += 1
        for _ in range(opened):
            stack.append([])
            choices.append([])
        if token == "|":
            choices[-1].append(stack[-1])
            stack[-1] = []
        elif "|" in token:
            stack[-1].append([[word] for word in token.split("|")])
        elif token and token != "...":
            stack[-1].append(token)
        for _ in range(closed):
            alternatives = choices.pop() + [stack.pop()]
            stack[-1].append(alternatives)
    assert len(stack) == 1, f"unbalanced brackets in {' '.join(tokens)}"
    tree = stack[0]

    def width(sequence):
        return max([1] + [max(len(item), *(width(alt) for alt in item))
                          for item in sequence if isinstance(item, list)])

    def realise(sequence, i):
        words = []
        for item in sequence:
            if isinstance(item, list):
                words += realise(item[i % len(item)], i)
            else:
                words.append(item)
        return words

    return [realise(tree, i) for i in range(width(tree))]


def _substitute(argv):
    return [PLACEHOLDERS.get(token, token) for token in argv]


def _takes_value(subparser, option):
    action = subparser._option_string_actions.get(option)
    return action is not None and action.nargs != 0


def example(where, text, before=()):
    """The :class:`Example` of one command as written (``fliss ...``)."""
    body = _PREFIX.sub("", text.replace("\\|", "|"), count=1).strip()
    tokens = shlex.split(body, comments=True)
    argvs = [_substitute(argv) for argv in _alternatives(tokens)]
    mention = None
    if argvs[0]:
        subparser = subparsers().get(argvs[0][0])
        last = argvs[0][-1]
        if subparser is not None and last.startswith("-") and _takes_value(subparser, last):
            mention = last
            argvs = [argv[:-1] for argv in argvs]
    return Example(where, " ".join(text.split()), argvs, [list(argv) for argv in before],
                   mention)


def _in_session(example):
    """An example of a session that reaches a board and names no port (``fliss capture ...``)
    uses the port of the example above it that names one."""
    ports = [argv[argv.index("--port") + 1] for argv in example.before if "--port" in argv]
    if example.command in SESSION_COMMANDS and ports:
        example.argvs = [argv if "--port" in argv else [argv[0], "--port", ports[-1], *argv[1:]]
                         for argv in example.argvs]
    return example


def _commands_of_line(text):
    # "fliss a ...; fliss b ..." is two commands
    return [part.strip() for part in re.split(r";\s*(?=(?:\$ )?(?:\.venv/bin/)?fliss )", text)]


def doc_examples(path) -> List[Example]:
    """The examples of one Markdown file, in order."""
    name = path.relative_to(ROOT).as_posix()
    lines = path.read_text().splitlines()
    found = []
    fenced = set()
    inside, session = False, []
    number = 0
    while number < len(lines):
        line = lines[number]
        if line.startswith("```"):
            inside, session = not inside, []
            fenced.add(number)
            number += 1
            continue
        if not inside:
            number += 1
            continue
        fenced.add(number)
        first = number
        text = line.strip()
        while text.endswith("\\") and number + 1 < len(lines):
            number += 1
            fenced.add(number)
            text = text[:-1] + " " + lines[number].strip()
        if _PREFIX.match(text):
            for command in _commands_of_line(text):
                found.append(_in_session(example(f"{name}:{first + 1}", command, session)))
                if found[-1].command in SESSION_COMMANDS:
                    session = session + found[-1].argvs[:1]
                if found[-1].command not in SESSION_READERS:
                    found[-1].before = []
        number += 1
    # inline code spans outside the fenced blocks
    prose = "\n".join("" if i in fenced else line for i, line in enumerate(lines))
    for match in re.finditer(r"(`+)(.+?)\1", prose, flags=re.DOTALL):
        text = " ".join(match.group(2).split())
        if _PREFIX.match(text) and text != "fliss":
            line = prose.count("\n", 0, match.start()) + 1
            found.append(example(f"{name}:{line}", text))
    return sorted(found, key=lambda e: int(e.where.rsplit(":", 1)[1]))


def _help_values(help_text, nargs):
    """The example values an option's help gives (see the module), as argument tails."""
    values = []
    for group in re.findall(r"\(([^()]*)\)", help_text):
        group = re.sub(r"^(?:e\.g\.|for example)\s+", "", group.strip())
        group = group.rsplit(": ", 1)[-1]
        parts = [re.sub(r"\s+for\s.*$", "", part.strip())
                 for part in re.split(r",\s*(?:or\s+)?|\s+or\s+", group)]
        parts = [part for part in parts if part != "..."]
        tails = [part.split() for part in parts]
        width = nargs if isinstance(nargs, int) else 1
        if parts and all(len(tail) == width and all(_VALUE.fullmatch(word) for word in tail)
                         for tail in tails):
            values += tails
    return values


def help_examples() -> List[Example]:
    """The examples of every sub-command's ``--help``: code spans, and values of options."""
    found = []
    for command, subparser in subparsers().items():
        where = f"fliss {command} --help"
        texts = [subparser.description or "", subparser.epilog or ""]
        texts += [group.title or "" for group in subparser._action_groups]
        texts += [action.help or "" for action in subparser._actions]
        for text in texts:
            for span in re.findall(r"`([^`]+)`", text):
                if _PREFIX.match(span) and span != "fliss":
                    found.append(example(f"{where}: `{span}`", span))
        for action in subparser._actions:
            if not action.option_strings or not action.help or action.nargs == 0:
                continue
            option = action.option_strings[-1]
            for tail in _help_values(action.help, action.nargs):
                found.append(Example(f"{where}: {option} {' '.join(tail)}",
                                     f"fliss {command} {option} {' '.join(tail)}",
                                     [[command, option, *tail]]))
    return found


def all_examples() -> List[Example]:
    """Every example, the docs' first (by file and line), then the help texts'."""
    examples = [e for path in DOCS for e in doc_examples(path)]
    return examples + help_examples()


def cases(examples) -> List[Tuple[str, Example, List[str]]]:
    """(id, example, argv) for each argument list of each example; ids are ``file:line`` (with
    ``#i`` for the ``i``-th alternative, and a letter for a second example on one line)."""
    out, seen = [], {}
    for e in examples:
        base = e.where
        seen[base] = seen.get(base, 0) + 1
        if seen[base] > 1:
            base += "abcdefgh"[seen[base] - 1]
        for i, argv in zip(count(1), e.argvs):
            out.append((base if len(e.argvs) == 1 else f"{base}#{i}", e, argv))
    return out
