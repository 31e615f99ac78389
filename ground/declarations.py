"""A ground tool's declarations on the bus, held for as long as it is entered."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from contextlib import ExitStack
from typing import Self

from fleet.transport.bus import Declaration

Enter = Callable[[Declaration], None]


class Declarations(ABC):
    """Declares its subscriptions and queryables on entering (`_declare`), undeclares
    them all on leaving, and at once if one of them cannot be declared."""

    def __init__(self) -> None:
        self._stack = ExitStack()

    @abstractmethod
    def _declare(self, enter: Enter) -> None:
        """Declare everything, each declaration through `enter`."""

    def _enter(self, declaration: Declaration) -> None:
        self._stack.callback(declaration.undeclare)

    def __enter__(self) -> Self:
        try:
            self._declare(self._enter)
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stack.close()
