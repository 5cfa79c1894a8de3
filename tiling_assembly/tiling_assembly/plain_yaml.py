"""A fast reader for the plain YAML that structure files are written in.

PyYAML takes about a second to read a 10,000-tile structure even with libyaml's parser (its
constructor builds the values in Python, node by node): most of what loading cost. Structure files
use a small part of YAML: block mappings and sequences indented with spaces, flow sequences and
mappings on one line, comments, and scalars that are numbers, booleans, null, names or simply
quoted strings. `read_plain_yaml` reads exactly that part and gives up (returns NOT_PLAIN) at the
first thing outside it; the caller then reads the text with PyYAML, which also words every error.
So a document read here has the values PyYAML would give it, and anything else is PyYAML's.
"""

from __future__ import annotations

import re
from typing import Any

NOT_PLAIN: Any = object()  # what `read_plain_yaml` returns for text outside the plain subset
_UNSEEN: Any = object()

# Characters that PyYAML refuses or treats specially (line breaks other than "\n", tabs, a byte
# order mark): text holding any of them is left to PyYAML. The class for all of Unicode takes
# 8 ms to compile, so it is compiled only for text that is not ASCII.
_OUTSIDE_ASCII_SUBSET = re.compile("[^\n\x20-\x7e]")
_OUTSIDE_SUBSET = "[^\n\x20-\x7e\xa0-\u2027\u202a-\ud7ff\ue000-\ufefe\uff00-\ufffd\U00010000-\U0010ffff]"

# Plain scalars, resolved as PyYAML's implicit resolvers (YAML 1.1) resolve them. Each pattern is
# a part of PyYAML's own for its type that excludes every other type; anything else is not plain.
_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)\Z")
_FLOAT = re.compile(r"[-+]?[0-9]+\.[0-9]*(?:[eE][-+][0-9]+)?\Z")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-/]*\Z")  # a letter first: only bool and null compete
_WORDS: dict[str, Any] = {
    **dict.fromkeys(("yes", "Yes", "YES", "true", "True", "TRUE", "on", "On", "ON"), True),
    **dict.fromkeys(("no", "No", "NO", "false", "False", "FALSE", "off", "Off", "OFF"), False),
    **dict.fromkeys(("~", "null", "Null", "NULL"), None),
}
_QUOTED = re.compile(r"'[^']*'\Z|\"[^\"\\]*\"\Z")  # no escapes: the text between is the string

_MARKER_LINE = re.compile(r"^(?:---|\.\.\.|%)", re.MULTILINE)  # document markers and directives
# "key:" or "key: value" (comments already cut off); the key is a scalar as above
_KEY_LINE = re.compile(r"(?P<key>'[^']*'|\"[^\"\\]*\"|[A-Za-z0-9_~+\-][A-Za-z0-9_.+\-/]*):(?: +(?P<rest>.*))?\Z")
# one token of a flow collection: an indicator, or a scalar (no spaces: "a b" is not plain here)
_FLOW_TOKEN = re.compile(r" *(?:([\[\]{},])|(:)(?= )|('[^']*'|\"[^\"\\]*\"|[^ \[\]{},:'\"]+))")


class _NotPlainError(Exception):
    """The text uses YAML beyond the plain subset."""


def read_plain_yaml(text: str) -> Any:
    """The document in `text` as PyYAML's safe loader reads it, or NOT_PLAIN (see the module
    docstring). Duplicate keys are also NOT_PLAIN: the strict loader reports them."""
    try:
        return _Reader(text).document()
    except (_NotPlainError, RecursionError):  # nesting deeper than Python's stack: PyYAML's to judge
        return NOT_PLAIN


def _scalar(text: str) -> Any:
    """The value of a scalar written as `text`, or _NotPlainError."""
    if text in _WORDS:
        return _WORDS[text]
    if _INT.match(text):
        return int(text)
    if _FLOAT.match(text):
        return float(text)
    if _NAME.match(text):
        return text
    if _QUOTED.match(text):
        return text[1:-1]
    raise _NotPlainError


def _is_sequence_entry(content: str) -> bool:
    return content == "-" or content.startswith("- ")


def _without_comment(content: str) -> str:
    """The line's content before its comment. Quotes could hold " #", so they are left to PyYAML."""
    if "'" in content or '"' in content:
        raise _NotPlainError
    cut = content.find(" #")
    if cut < 0:
        raise _NotPlainError  # "a#b" is a plain scalar in YAML, but none of ours
    return content[:cut].rstrip(" ")


class _Reader:
    """Block structure by indentation: each node starts at a column, and a line at a column less
    than its node's ends the node. `- ` opens a node two or more columns to the right on the same
    line, which is then read as if it started a line there."""

    def __init__(self, text: str) -> None:
        outside = _OUTSIDE_ASCII_SUBSET if text.isascii() else re.compile(_OUTSIDE_SUBSET)
        if outside.search(text) or _MARKER_LINE.search(text):
            raise _NotPlainError
        # (column, content) of the lines that hold a node
        self.lines: list[tuple[int, str]] = [
            (len(line) - len(content), content.rstrip(" "))
            for line in text.split("\n")
            if (content := line.lstrip(" "))
        ]
        if "#" in text:
            self.lines = [(column, _without_comment(content)) if "#" in content else (column, content)
                          for column, content in self.lines if content[0] != "#"]
        self.next = 0  # index in `lines` of the next line to read
        self.scalars: dict[str, Any] = {}  # text -> value: big structures repeat their numbers

    def document(self) -> Any:
        if not self.lines:
            raise _NotPlainError  # empty: PyYAML says what that is
        value = self.block(self.lines[0][0])
        if self.next != len(self.lines):
            raise _NotPlainError
        return value

    def scalar(self, text: str) -> Any:
        try:
            return self.scalars[text]
        except KeyError:
            value = self.scalars[text] = _scalar(text)
            return value

    def block(self, column: int) -> Any:
        """The block node whose first line (the next) starts at `column`."""
        if _is_sequence_entry(self.lines[self.next][1]):
            return self.sequence(column)
        return self.mapping(column)

    def ended(self, column: int) -> None:
        """After a node at `column`: a deeper line would belong to nothing we read."""
        if self.next < len(self.lines) and self.lines[self.next][0] > column:
            raise _NotPlainError

    def mapping(self, column: int) -> dict[Any, Any]:
        lines, mapping, at, count = self.lines, {}, self.next, len(self.lines)  # locals, for speed
        while at < count and lines[at][0] == column:
            match = _KEY_LINE.match(lines[at][1])
            if match is None:
                break
            key = self.scalar(match["key"])
            if key in mapping:
                raise _NotPlainError
            at += 1
            rest = match["rest"]
            if rest:
                value = self.scalars.get(rest, _UNSEEN)  # the inline value, looked up without a call
                mapping[key] = self.inline(rest) if value is _UNSEEN else value
            else:
                self.next = at
                mapping[key] = self.nested(column, compact_sequence=True)
                at = self.next
        self.next = at
        if not mapping:
            raise _NotPlainError  # a scalar on a line of its own, or something else we do not read
        self.ended(column)
        return mapping

    def sequence(self, column: int) -> list[Any]:
        lines, items, at, count = self.lines, [], self.next, len(self.lines)  # locals, for speed
        while at < count:
            start, content = lines[at]
            if start != column or not (content[:2] == "- " or content == "-"):
                break
            rest = content[2:].lstrip(" ")
            if not rest:
                self.next = at + 1
                items.append(self.nested(column, compact_sequence=False))
                at = self.next
            elif rest[:2] == "- " or rest == "-" or (":" in rest and rest[0] not in "[{" and _KEY_LINE.match(rest)):
                inner = column + len(content) - len(rest)  # the node starts where its text does
                lines[at] = (inner, rest)
                self.next = at
                items.append(self.block(inner))
                at = self.next
            else:
                value = self.scalars.get(rest, _UNSEEN)  # the inline value, looked up without a call
                items.append(self.inline(rest) if value is _UNSEEN else value)
                at += 1
        self.next = at
        self.ended(column)
        return items

    def nested(self, column: int, *, compact_sequence: bool) -> Any:
        """The value on the lines after a key or `-` at `column` with nothing after it: a deeper
        block, a sequence at the key's own column (YAML allows that for a mapping's value), or
        null."""
        if self.next < len(self.lines):
            start, content = self.lines[self.next]
            if start > column:
                return self.block(start)
            if start == column and compact_sequence and _is_sequence_entry(content):
                return self.sequence(column)
        return None

    def inline(self, text: str) -> Any:
        """A value written after `key: ` or `- `: a scalar or a one-line flow collection."""
        if text[0] in "[{":
            return _FlowReader(text, self).document()
        return self.scalar(text)


class _FlowReader:
    """A flow sequence or mapping written on one line, e.g. `{id: 1, position: [0.1, 0, 0]}`."""

    def __init__(self, text: str, reader: _Reader) -> None:
        self.tokens: list[tuple[str, str]] = []  # (indicator or "", scalar text or "")
        position = 0
        while position < len(text):
            match = _FLOW_TOKEN.match(text, position)
            if match is None:
                raise _NotPlainError
            indicator, colon, scalar = match.groups()
            self.tokens.append((indicator or colon or "", scalar or ""))
            position = match.end()
        self.next = 0
        self.reader = reader

    def document(self) -> Any:
        value = self.node()
        if self.next != len(self.tokens):
            raise _NotPlainError
        return value

    def take(self) -> tuple[str, str]:
        if self.next >= len(self.tokens):
            raise _NotPlainError  # the collection goes on on the next line
        token = self.tokens[self.next]
        self.next += 1
        return token

    def node(self) -> Any:
        indicator, scalar = self.take()
        if indicator == "[":
            return self.items("]", self.node)
        if indicator == "{":
            pairs = self.items("}", self.pair)
            mapping = dict(pairs)
            if len(mapping) != len(pairs):
                raise _NotPlainError  # a duplicate key
            return mapping
        if indicator:
            raise _NotPlainError
        return self.reader.scalar(scalar)

    def pair(self) -> tuple[Any, Any]:
        indicator, key = self.take()
        if indicator or self.take()[0] != ":":
            raise _NotPlainError  # complex keys and keys without values are PyYAML's
        return self.reader.scalar(key), self.node()

    def items(self, closing: str, item: Any) -> list[Any]:
        """Entries separated by commas up to `closing` (no trailing comma, no empty entries)."""
        if self.next < len(self.tokens) and self.tokens[self.next][0] == closing:
            self.next += 1
            return []
        entries = [item()]
        while True:
            indicator, _ = self.take()
            if indicator == closing:
                return entries
            if indicator != ",":
                raise _NotPlainError
            entries.append(item())
