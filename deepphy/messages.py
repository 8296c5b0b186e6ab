"""One-line messages for the user from errors raised elsewhere (YAML, Pydantic, anything).

Every user-facing error in deepphy is one line: these turn multi-line library messages into
that, in one place, so a suite file, a models file and a command's flags read alike.
"""

from __future__ import annotations

TYPE_CHECKING = False  # typing's, without importing it: one_line writes a command's quick error lines
if TYPE_CHECKING:
    from pydantic import ValidationError


def one_line(text: str) -> str:
    """`text` with its lines joined by single spaces (blank lines dropped)."""
    return " ".join(line.strip() for line in text.splitlines() if line.strip())


def validation_message(error: ValidationError) -> str:
    """The first problem Pydantic found, as `where: what` (`what` alone at the top level),
    without Pydantic's "Value error, " prefix on our own validators' messages."""
    first = error.errors()[0]
    where = ".".join(map(str, first["loc"]))
    what = one_line(first["msg"].removeprefix("Value error, "))
    return f"{where}: {what}" if where else what
