"""A ground tool's Zenoh declarations, held for as long as it is entered."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from contextlib import AbstractContextManager, ExitStack
from types import TracebackType
from typing import Any, Self

Enter = Callable[[AbstractContextManager[Any]], Any]


class Declarations(ABC):
    """Declares its subscriptions and queryables on entering (`_declare`), undeclares
    them all on leaving, and at once if one of them cannot be declared."""

    def __init__(self) -> None:
        self._stack = ExitStack()

    @abstractmethod
    def _declare(self, enter: Enter) -> None:
        """Declare everything, each declaration through `enter`."""

    def __enter__(self) -> Self:
        try:
            self._declare(self._stack.enter_context)
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stack.close()
