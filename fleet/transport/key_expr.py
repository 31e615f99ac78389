"""A key expression a user typed (`ground-cli keys EXPR`, `fleet record KEYEXPR`), checked
before any session is asked to use it.

Zenoh refuses a malformed expression only when it is declared, with an exception whose
text ends in a Rust source path; a command would die with a traceback. Checked here,
it is one line saying what is wrong and how key expressions are written. An expression
Zenoh can put in canonical form by itself (`fleet/**/**`, `fleet/**/*`) is taken in that
form: it means the same keys.
"""

from __future__ import annotations

import zenoh

from fleet.errors import FleetError
from fleet.transport.zenoh_config import error_text

#: How key expressions are written, said after what was wrong with one.
HOW_TO_WRITE = (
    "write chunks separated by single `/`, with `*` for any one chunk and `**` for any "
    "number of them (e.g. fleet/** or fleet/uav/*/telemetry)"
)


class KeyExprError(FleetError, ValueError):
    """Not a key expression; the message says why and how to write one."""


def checked_key_expr(text: str) -> str:
    """`text` as a key expression in Zenoh's canonical form; KeyExprError if it is none."""
    try:
        return str(zenoh.KeyExpr.autocanonize(text))
    except zenoh.ZError as error:
        why = error_text(error)
        # Zenoh's text repeats the expression: "Invalid Key Expr `x`: why".
        why = why.partition(": ")[2] or why
        raise KeyExprError(f"{text!r} is not a key expression ({why}): {HOW_TO_WRITE}") from None
