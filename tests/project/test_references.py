"""Every module path and name that README.md, docs/*.md and the package's docstrings and comments
give exists.

What is read: README.md and docs/*.md (all of their text), and in every Python file of the
package's trees (``fliss/``, ``hdl/``, ``protocol/``, ``analysis/``, ``sim/``, ``host/``,
``boards/``, ``formal/``) its comments and docstrings (every string that is a statement of its
own: module, class, function and attribute docstrings) for all the references below, and its
other strings (messages, help texts: "see docs/boards.md") for file paths and file names only
(a dotted name there may be a logger's). And the build's files (:data:`BUILD_FILES`: the
Makefile, pyproject.toml, setup.py, .ci/run), all of their text, for all but Sphinx roles and
Markdown links.

What is a reference, and how it is checked:

* **A file path**: a word that starts with one of the repository's top-level folders
  (:data:`ROOTS`) and a ``/``, and is not part of a longer path or an address (no letter, ``/``,
  ``.``, ``~``, ``:`` or ``-`` right before it). It must exist relative to the repository root,
  as a file or a folder. Trailing punctuation is not part of it; ``path:123`` (a line) and
  ``path::name`` (a test) are the file ``path``, and with ``::name`` the file must define
  ``name``; ``path#anchor`` is checked as a Markdown link (below). A path with a glob
  character (``tests/test_cocotb_*``) must match at least one file. A test file named as
  ``tests/NAME`` may sit in a layer's folder (``tests/<layer>/NAME``): the one file of that name
  under ``tests/`` is taken (a glob, the files under ``tests/``), so that references to tests
  survive their moves between layers. ``fliss/<tree>/...`` is a
  path inside the installed package: it is checked as ``<tree>/...`` (``fliss/hdl/top.py`` is
  ``hdl/top.py``). Paths under folders the repository does not keep (``build/``,
  ``sim_build/``, ``~/.cache``, ...) are outputs, not references, and are not read.
* **A file name** alone in a code span (``cobs.py``, ``depth.md``, named after a folder the
  text gave before): a ``.py`` or ``.md`` file of that name is somewhere in those folders or at
  the root.
* **A dotted name** ``fliss.a.b.Name`` (also ``fliss.a.b:Name``, as ``--design`` takes it):
  the longest prefix that imports is a module and the rest are attributes of it.
* **A Sphinx role** in a Python file (``:mod:``, ``:class:``, ``:func:``, ``:meth:``,
  ``:attr:``, ``:data:``, ``:exc:``, ``:obj:``, with or without ``~``, trailing ``()`` and a
  ``title <...>`` ignored):

  - ``.name`` / ``..name`` is relative, as in an import: ``.lfsr`` in ``hdl/__init__.py`` is
    ``fliss.hdl.lfsr``, ``..protocol`` in ``hdl/link/uart.py`` is ``fliss.hdl.protocol``.
    Failing that, Sphinx's reading is accepted too: the name in the file's own module;
  - any other name is looked up where the text is: in the enclosing classes (innermost first,
    with their bases), then in the module's namespace, then in the builtins, and last as an
    absolute name (``fliss.hdl.top.FlissTop``, ``amaranth.hdl.Array``: as a dotted name
    above). So a name the module imports (``stream.Signature`` after ``from amaranth.lib
    import stream``) resolves, and a bare name the module neither defines nor imports does
    not, not even one of an outside library.

  A class member resolves if the class has it as an attribute or an annotation (a
  ``wiring.Component``'s fixed ports), or if the file that defines the class or one of its
  bases assigns ``self.name`` (an instance attribute) or declares a port ``"name": In(...)`` /
  ``Out(...)`` (a port that depends on the parameters).

  A module that cannot be imported here for want of an optional extra (``boards/ulx3s.py``
  without amaranth-boards) is read from its source instead: its top-level classes (with their
  methods, class attributes and ``self.`` names), functions, assignments and the names it
  imports; a member of anything but a class is taken as there.
* **A make target**: ``make TARGET`` in a code span (in the Markdown files, the Python texts
  and the build's files), in a Markdown file's code blocks and in ``.ci/run``: ``TARGET`` is a
  target of the Makefile (variables before it, ``make BOARD=ulx3s bitstream``, are skipped).
* **A class or function name** in a code span of a Markdown file (a capitalised identifier
  without underscores, of more than three characters: ``DualPortBanks``,
  ``FlissTop.register_maxima()``, not ``Wm``): a class, function or
  name defined, assigned or imported somewhere in the package's trees, ``tests/``,
  ``benchmarks/`` or ``examples/``, a builtin, or a name of an outside library listed in
  :data:`OUTSIDE_NAMES` (checked there when that library is installed).
* **A package's list of its modules**: a package's ``__init__.py`` docstring that lists its
  modules (a bullet that starts with ``:mod:`.name```) names every one of them (each module and
  subpackage whose name does not start with ``_``) somewhere in it.
* **A Markdown link** ``[text](target)`` in a Markdown file (outside code blocks), unless the
  target is an address (``scheme:``): the file, relative to the Markdown file, exists, and
  ``#anchor`` is one of its headings' anchors by GitHub's rule (lower case, punctuation other
  than ``-`` and ``_`` dropped, spaces to ``-``, ``-1``, ``-2``, ... for repeats).

Every broken reference is listed in one failure, as ``file:line: kind: reference (why)``.
"""

import ast
import builtins
import functools
import glob
import importlib
import importlib.util
import inspect
import re
import sys
import tokenize
from pathlib import Path


ROOT = Path(__file__).resolve().parents[2]

#: The package's trees: folder -> package (as setup.py lays them out).
TREES = {"fliss": "fliss", "hdl": "fliss.hdl", "protocol": "fliss.protocol",
         "analysis": "fliss.analysis", "sim": "fliss.sim", "host": "fliss.host",
         "boards": "fliss.boards", "formal": "fliss.formal"}

#: Top-level folders a path reference starts with.
ROOTS = (*TREES, "tests", "docs", "examples", "benchmarks", ".ci")

#: The build's files, read (all of their text) for file paths and names and dotted names.
BUILD_FILES = ("Makefile", "pyproject.toml", "setup.py", ".ci/run")

_PATH = re.compile(r"(?<![\w/.~:\-])((?:%s)/[\w./*?\-]*(?:::\w+|#[\w\-]+)?)"
                   % "|".join(re.escape(root) for root in ROOTS))
_BARE = re.compile(r"`+([\w\-]+\.(?:py|md))`+")
_DOTTED = re.compile(r"(?<![\w.])fliss(?:\.\w+)+(?::\w+)?")
_ROLE = re.compile(r":(mod|class|func|meth|attr|data|exc|obj):`~?([^`]+)`")
_LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
_SPAN = re.compile(r"`+([^`]+)`+")
_MAKE = re.compile(r"(?<![\w./$-])make +(?:[A-Z_]+=\S* +)*([a-z][\w-]*)")
_CLASS = re.compile(r"^([A-Z][A-Za-z0-9]*[a-z][A-Za-z0-9]*)(?:$|[(.\[])")
_LISTED = re.compile(r"^\s*\* :mod:`~?\.(\w+)", flags=re.MULTILINE)

#: Names of outside libraries the docs give in code spans: name -> where it is.
OUTSIDE_NAMES = {"PtuWriter": "ptufile.PtuWriter", "GenericT3": "ptufile.PtuRecordType.GenericT3",
                 "CLSMImage": "tttrlib.CLSMImage", "PtuFile": "ptufile.PtuFile"}


# Sources ----------------------------------------------------------------------------------------

def _markdown_files():
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _python_files():
    for folder in TREES:
        yield from sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


def _module_name(path):
    # The module a file is, or None outside a package (a data folder's script).
    relative = path.relative_to(ROOT)
    folder, *parts = relative.with_suffix("").parts
    for depth in range(len(parts)):
        if not (ROOT / folder / Path(*parts[:depth]) / "__init__.py").exists():
            return None
    if parts and parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join([TREES[folder], *parts])


def _python_texts(path):
    """``(line, text, classes, roles)`` of each comment, docstring and other string of ``path``;
    ``classes`` is the chain of names of the classes the text is in, ``roles`` whether it is
    read for Sphinx roles (comments and docstrings)."""
    source = path.read_text()
    lines = [line.encode() for line in source.splitlines(keepends=True)]
    tree = ast.parse(source)
    spans = [(node.lineno, node.end_lineno, node.name) for node in ast.walk(tree)
             if isinstance(node, ast.ClassDef)]
    with path.open("rb") as file:
        for token in tokenize.tokenize(file.readline):
            if token.type == tokenize.COMMENT:
                line = token.start[0]
                classes = tuple(name for start, end, name in sorted(spans) if start <= line <= end)
                yield line, token.string, classes, True
    docstrings = set()         # and the parts of f-strings, read as a whole
    for node, classes in _walk(tree, ()):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str):
            docstrings.add(id(node.value))
            yield node.lineno, _segment(lines, node), classes, True
        elif isinstance(node, ast.JoinedStr):
            docstrings.update(id(value) for value in node.values)
            yield node.lineno, _segment(lines, node), classes, False
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and id(node) not in docstrings:
            yield node.lineno, _segment(lines, node), classes, False


def _segment(lines, node):
    # The source text of ``node`` (offsets are in bytes).
    if node.lineno == node.end_lineno:
        return lines[node.lineno - 1][node.col_offset:node.end_col_offset].decode()
    return b"".join([lines[node.lineno - 1][node.col_offset:], *lines[node.lineno:node.end_lineno - 1],
                     lines[node.end_lineno - 1][:node.end_col_offset]]).decode()


def _walk(node, classes):
    for child in ast.iter_child_nodes(node):
        yield child, classes
        yield from _walk(child, (*classes, child.name) if isinstance(child, ast.ClassDef)
                         else classes)


# Checks -----------------------------------------------------------------------------------------

def _anchors(markdown):
    anchors, seen, fenced = set(), {}, False
    for line in markdown.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        heading = re.match(r"#{1,6} +(.*?) *#*$", line)
        if heading and not fenced:
            slug = re.sub(r"[^\w\- ]", "", heading.group(1).lower()).replace(" ", "-")
            count = seen.get(slug, 0)
            seen[slug] = count + 1
            anchors.add(slug if count == 0 else f"{slug}-{count}")
    return anchors


def _check_link(base, target):
    # None if the link's file (and heading) exist, else why not.
    file, _, anchor = target.partition("#")
    path = (base / file).resolve() if file else None
    if path is not None and not path.exists():
        return "no such file"
    if anchor:
        markdown = path or base
        if markdown.suffix != ".md":
            return None
        if anchor not in _anchors(markdown):
            return f"no heading #{anchor} in {markdown.relative_to(ROOT)}"
    return None


@functools.cache
def _file_names():
    names = {path.name for path in ROOT.iterdir() if path.is_file()}
    for root in ROOTS:
        names |= {path.name for path in (ROOT / root).rglob("*") if path.is_file()}
    return names


def _test_file(path):
    # ``tests/NAME`` kept in a layer's folder: the one path under tests/ of that name (or glob).
    parts = path.split("/")
    if len(parts) != 2 or parts[0] != "tests":
        return None
    found = [p for p in (ROOT / "tests").rglob(parts[1]) if "__pycache__" not in p.parts]
    if any(c in parts[1] for c in "*?"):
        return path if found else None
    return str(found[0].relative_to(ROOT)) if len(found) == 1 else None


def _check_path(reference):
    reference = reference.rstrip(".,;:")
    path, _, test = reference.partition("::")
    path, _, anchor = path.partition("#")
    parts = path.split("/")
    if parts[0] == "fliss" and len(parts) > 1 and parts[1] in TREES and parts[1] != "fliss":
        path = "/".join(parts[1:])          # a path inside the installed package
    if any(c in path for c in "*?"):
        found = glob.glob(str(ROOT / path)) or _test_file(path)
        return None if found else "matches no file"
    if not (ROOT / path).exists():
        path = _test_file(path)
        if path is None:
            return "no such file or folder"
    if test and not re.search(rf"^\s*(async )?def {test}\b|^class {test}\b",
                              (ROOT / path).read_text(), flags=re.MULTILINE):
        return f"{path} defines no {test}"
    if anchor:
        return _check_link(ROOT, f"{path}#{anchor}")
    return None


def _import(name):
    # The module ``name``; a _Source of its file when its import fails for want of an optional
    # extra; ImportError when there is no such module.
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as error:
        if error.name and name.startswith(error.name):
            raise
        spec = importlib.util.find_spec(name)
    except ImportError:
        spec = importlib.util.find_spec(name)
    return _Source.of(Path(spec.origin))


def _resolve_absolute(name):
    # The object named ``name`` (a module, then attributes), or raise LookupError.
    parts = name.split(".")
    for count in range(len(parts), 0, -1):
        try:
            obj = _import(".".join(parts[:count]))
        except ImportError:
            continue
        for attribute in parts[count:]:
            obj = _member(obj, attribute)
        return obj
    raise LookupError(name)


def _member(obj, name):
    # ``obj.name``, or for a class also an annotation, a ``self.name`` in its file or a port.
    if isinstance(obj, (_Source, _SourceClass)):
        return obj.member(name)
    if hasattr(obj, name):
        return getattr(obj, name)
    if inspect.isclass(obj):
        for cls in obj.__mro__:
            if name in getattr(cls, "__annotations__", {}):
                return None
            if _assigned(name, _file_text(getattr(sys.modules.get(cls.__module__), "__file__",
                                                  None))):
                return None
    raise LookupError(name)


def _assigned(name, text):
    return re.search(rf"\bself\.{name}\b\s*(=|,)|[\"']{name}[\"']\s*:\s*(In|Out)\(", text)


@functools.cache
def _file_text(path):
    return Path(path).read_text() if path and path.endswith(".py") else ""


class _Any:
    # A name of a module read as source that is not a class: any member is taken as there.
    def member(self, name):
        return self


class _SourceClass:
    # A class of a module read as source: its methods, class attributes and annotations,
    # and the names it assigns to ``self.``.
    def __init__(self, node, text):
        self.names = {target.id for stmt in node.body
                      for target in getattr(stmt, "targets", [getattr(stmt, "target", None)])
                      if isinstance(target, ast.Name)}
        self.names |= {stmt.name for stmt in node.body if hasattr(stmt, "name")}
        self.text = ast.get_source_segment(text, node)

    def member(self, name):
        if name in self.names or _assigned(name, self.text):
            return _Any()
        raise LookupError(name)


class _Source:
    """A module that cannot be imported (an optional extra is missing), read from its source:
    its top-level classes, functions and assignments, and the names it imports (those that
    import here are the real objects, the others are taken as there)."""

    @classmethod
    @functools.cache
    def of(cls, path):
        return cls(path)

    def __init__(self, path):
        self.__file__ = str(path)
        text = path.read_text()
        self.names = {}
        for node in ast.parse(text).body:
            if isinstance(node, ast.ClassDef):
                self.names[node.name] = _SourceClass(node, text)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                self.names[node.name] = _Any()
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                for target in getattr(node, "targets", [getattr(node, "target", None)]):
                    if isinstance(target, ast.Name):
                        self.names[target.id] = _Any()
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                for alias in node.names:
                    self.names[(alias.asname or alias.name).split(".")[0]] = _Any()

    def member(self, name):
        if name in self.names:
            return self.names[name]
        raise LookupError(name)


def _resolve_role(target, module, classes):
    target = re.sub(r".*<(.*)>$", r"\1", target.strip()).removesuffix("()")
    if module is None:
        return _resolve_absolute(target)
    namespace = _import(module)
    if target.startswith("."):
        dots = len(target) - len(target.lstrip("."))
        package = module if namespace.__file__.endswith("__init__.py") else module.rpartition(".")[0]
        for _ in range(dots - 1):
            package = package.rpartition(".")[0]
        rest = target[dots:]
        try:
            return _resolve_absolute(f"{package}.{rest}" if rest else package)
        except LookupError:
            target = rest                   # Sphinx: the name in the current module
    head, *rest = target.split(".")
    scopes, obj = [namespace], namespace
    for name in classes:
        try:
            obj = _member(obj, name)
        except LookupError:
            break
        scopes.insert(0, obj)
    for scope in scopes:
        try:
            obj = _member(scope, head)
        except LookupError:
            continue
        for attribute in rest:
            obj = _member(obj, attribute)
        return obj
    if hasattr(builtins, head) and not rest:
        return getattr(builtins, head)
    return _resolve_absolute(target)


def _check_name(check, *args):
    try:
        check(*args)
    except LookupError as error:
        return f"{error.args[0]} not found"
    except Exception as error:     # an import that fails is a broken reference too
        return f"{type(error).__name__}: {error}"
    return None


def _text_problems(text, names=True):
    # (line offset, kind, reference, why) of the paths (and dotted names) in ``text``.
    for offset, line in enumerate(text.splitlines()):
        for match in _PATH.finditer(line):
            why = _check_path(match.group(1))
            if why:
                yield offset, "path", match.group(1), why
        for match in _BARE.finditer(line):
            if match.group(1) not in _file_names():
                yield offset, "file", match.group(1), "no file of that name"
        for match in _DOTTED.finditer(line if names else ""):
            why = _check_name(_resolve_absolute, match.group(0).replace(":", "."))
            if why:
                yield offset, "name", match.group(0), why


@functools.cache
def _make_targets():
    makefile = (ROOT / "Makefile").read_text()
    heads = re.findall(r"^([\w.\- ]+?)\s*::?(?!=)", makefile, flags=re.MULTILINE)
    return {target for head in heads for target in head.split()}


def _make_problems(text, *, spans=True):
    # (line offset, kind, reference, why) of the make targets of ``text``'s code spans (or of
    # all of it) that the Makefile does not have.
    for offset, line in enumerate(text.splitlines()):
        for part in ([m.group(1) for m in _SPAN.finditer(line)] if spans else [line]):
            for match in _MAKE.finditer(part):
                if match.group(1) not in _make_targets():
                    yield offset, "make target", match.group(1), "not in the Makefile"


@functools.cache
def _defined_names():
    # Every name a class, function, assignment or import gives in the repository's Python files.
    names = set(dir(builtins))
    for folder in (*TREES, "tests", "benchmarks", "examples", "docs"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                    names.add(node.name)
                elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                    names.add(node.id)
                elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                    names.add(node.attr)
                elif isinstance(node, (ast.Import, ast.ImportFrom)):
                    names.update((alias.asname or alias.name).split(".")[-1]
                                 for alias in node.names)
    return names


def _class_problems(text):
    # (line offset, kind, reference, why) of the capitalised names in ``text``'s code spans
    # that nothing defines.
    for offset, line in enumerate(text.splitlines()):
        for span in _SPAN.finditer(line):
            match = _CLASS.match(span.group(1))
            if match and len(match.group(1)) > 3 and match.group(1) not in _defined_names() \
                    and match.group(1) not in OUTSIDE_NAMES:
                yield offset, "name", match.group(1), "defined nowhere in the repository"


def _package_problems(init):
    # The modules of the package ``init`` (an __init__.py) that its docstring's list leaves out.
    doc = ast.get_docstring(ast.parse(init.read_text())) or ""
    if not _LISTED.search(doc):
        return []                   # not a list of its modules
    named = set(re.findall(r":mod:`~?\.(\w+)", doc))
    modules = {path.stem for path in init.parent.glob("*.py")} | \
        {path.parent.name for path in init.parent.glob("*/__init__.py")}
    return sorted(name for name in modules - named if not name.startswith("_"))


def test_outside_names_exist():
    # The outside libraries' names that the docs may give, where they are (when installed).
    for name, where in OUTSIDE_NAMES.items():
        module, _, rest = where.partition(".")
        library = importlib.util.find_spec(module)
        if library is None:
            continue
        obj = importlib.import_module(module)
        for attribute in rest.split("."):
            obj = getattr(obj, attribute)
        assert rest.split(".")[-1] == name and obj is not None


def _problems():
    problems = []
    for build in BUILD_FILES:
        text = (ROOT / build).read_text()
        for offset, kind, reference, why in [*_text_problems(text), *_make_problems(
                text, spans=build != ".ci/run")]:
            problems.append(f"{build}:{offset + 1}: {kind}: {reference} ({why})")
    for init in sorted(p for folder in TREES for p in (ROOT / folder).rglob("__init__.py")):
        for module in _package_problems(init):
            problems.append(f"{init.relative_to(ROOT)}:1: module list: leaves out .{module}")
    for markdown in _markdown_files():
        relative = markdown.relative_to(ROOT)
        text = markdown.read_text()
        for offset, kind, reference, why in [*_text_problems(text), *_make_problems(text),
                                             *_class_problems(text)]:
            problems.append(f"{relative}:{offset + 1}: {kind}: {reference} ({why})")
        fenced = False
        for number, line in enumerate(text.splitlines(), 1):
            if line.startswith("```"):
                fenced = not fenced
            for _, kind, reference, why in _make_problems(line, spans=not fenced):
                problems.append(f"{relative}:{number}: {kind}: {reference} ({why})")
            for match in _LINK.finditer("" if fenced else line):
                target = match.group(1)
                if re.match(r"[a-z]+:", target):
                    continue
                why = _check_link(markdown.parent, target)
                if why:
                    problems.append(f"{relative}:{number}: link: {target} ({why})")
    for source in _python_files():
        relative, module = source.relative_to(ROOT), _module_name(source)
        for start, text, classes, roles in _python_texts(source):
            for offset, kind, reference, why in [*_text_problems(text, names=roles),
                                                 *_make_problems(text if roles else "")]:
                problems.append(f"{relative}:{start + offset}: {kind}: {reference} ({why})")
            for offset, line in enumerate(text.splitlines() if roles else ()):
                for match in _ROLE.finditer(line):
                    why = _check_name(_resolve_role, match.group(2), module, classes)
                    if why:
                        problems.append(f"{relative}:{start + offset}: :{match.group(1)}: "
                                        f"{match.group(2)} ({why})")
    return list(dict.fromkeys(problems))       # (an f-string's parts are read with it)


def test_references_exist():
    problems = _problems()
    assert not problems, f"{len(problems)} broken references:\n" + "\n".join(problems)
