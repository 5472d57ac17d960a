"""Excerpts for error lines: a message that quotes what a file or the wire held shows a bounded part of it.

A value, a key or another error's text may be a 50,000-number list or a megabyte of hostile text; an error
line quotes at most a few hundred characters of it, so a refusal stays one readable line however large the
input was (docs/trust.md).
"""

from __future__ import annotations

__all__ = ["MAX_ERROR_LINE", "MAX_MESSAGE_LINE", "MAX_VALUE_QUOTE", "error_line", "excerpt", "quote"]

#: Characters of an error line that quotes what a file held (a value, a key, another error's line).
MAX_ERROR_LINE = 300
#: Characters of an error line of our own that may quote a little of a file: room for the valid keys or
#: the fixes it lists, not for a 50,000-number value.
MAX_MESSAGE_LINE = 1000
#: Characters of a value (its ``repr``) an error line quotes from a file: a file may hold a million numbers.
MAX_VALUE_QUOTE = 80


def excerpt(text: str, limit: int = MAX_ERROR_LINE, *, count_rest: bool = False) -> str:
    """``text`` cut to ``limit`` characters and marked ``...``; with ``count_rest``, followed by how many
    characters were left out (a command line's error, where the reader may want to know)."""
    if len(text) <= limit:
        return text
    if count_rest:
        return f"{text[:limit]}... ({len(text) - limit:,} characters more)"
    return f"{text[:max(limit - 3, 0)]}..."


def error_line(exc: BaseException, limit: int = MAX_ERROR_LINE) -> str:
    """An exception's first line (its type when it says nothing), cut to ``limit`` characters."""
    text = str(exc).strip()
    return excerpt(text.splitlines()[0] if text else type(exc).__name__, limit)


def quote(value: object, limit: int = MAX_VALUE_QUOTE) -> str:
    """A value read from a file or the wire, as an error line quotes it: its ``repr``, cut to ``limit``."""
    return excerpt(repr(value), limit)
