"""One ordered stream read by several readers, each at its own pace, none holding all of it.

Theory of operation
-------------------
A replay reads one recording in which the servo bus's bytes, the sensor board's, the
IMU's and the fed commands come interleaved in time order. Read up front, an hour of
it would be held in memory at once. :class:`Dealer` reads it once and lazily instead,
dealing each item to its reader's :class:`Hand`: a reader that asks while its hand
is empty makes the dealer read on, queueing what belongs to the others on the way.
Readers on virtual time move through the recording together, so each hand holds
what lies between its reader's time and the furthest reader's: memory stays bounded
however long the recording. (A reader that stops reading while the others go on
gathers the rest of its items, as a list read up front would have held them.)
"""

from __future__ import annotations

from collections import deque
from collections.abc import Hashable, Iterable, Iterator
from typing import Any, Generic, TypeVar

__all__ = ["BATCH", "Dealer", "Hand"]

K = TypeVar("K", bound=Hashable)
T = TypeVar("T")

BATCH = 32
"""Items dealt at a time: a call per item would cost a replay several per cent."""


class Dealer(Generic[K, T]):
    """Deals the ``(key, item)`` pairs of ``items`` to the hand of each key, as asked.

    Hands are made (:meth:`hand`) before the first is read from: an item whose key
    has no hand then is dropped. ``batch``: items read at a time (default
    :data:`BATCH`); 1 where the stream is itself another dealer's hand, whose reading
    ahead a batch would multiply.
    """

    def __init__(self, items: Iterable[tuple[K, T]], batch: int | None = None) -> None:
        self._items: Iterator[tuple[K, T]] = iter(items)
        self._batch = batch
        self._hands: dict[K, Hand[T]] = {}
        self.closed = False
        """:meth:`close` was called: the hands hold what was read, nothing more comes."""

    def hand(self, key: K) -> Hand[T]:
        """The hand of ``key`` (the same one each time)."""
        hand = self._hands.get(key)
        if hand is None:
            hand = self._hands[key] = Hand(self)
        return hand

    def deal(self) -> bool:
        """Read up to a batch more items into their hands; ``False`` once the stream is
        over."""
        hands = self._hands
        batch = self._batch or BATCH
        dealt = 0
        for key, item in self._items:
            hand = hands.get(key)
            if hand is not None:
                hand.queue.append(item)
            dealt += 1
            if dealt == batch:
                break
        return dealt > 0

    def close(self) -> None:
        """Stop reading (closing the stream, if it can be closed): the hands keep what
        they hold."""
        items, self._items = self._items, iter(())
        close = getattr(items, "close", None)
        if close is not None:
            close()
        self.closed = True


class Hand(Generic[T]):
    """One reader's items of a :class:`Dealer`, in stream order, read like a deque."""

    __slots__ = ("dealer", "queue")

    def __init__(self, dealer: Dealer[Any, T]) -> None:
        self.dealer = dealer
        self.queue: deque[T] = deque()
        """The items dealt and not yet taken."""

    @classmethod
    def of(cls, items: Iterable[T]) -> Hand[T]:
        """``items`` read as a hand: itself if it is one, else the only hand of a dealer
        of them."""
        if isinstance(items, Hand):
            return items
        return Dealer((None, item) for item in items).hand(None)

    def fill(self) -> bool:
        """Read on until an item is here; ``False`` at the end (a reader that takes
        from :attr:`queue` directly calls this when it is empty)."""
        queue, deal = self.queue, self.dealer.deal
        while not queue:
            if not deal():
                return False
        return True

    def __bool__(self) -> bool:
        """Whether an item is left (reading on until one is dealt here, or the end)."""
        return bool(self.queue) or self.fill()

    def peek(self) -> T | None:
        """The next item, left in place; ``None`` at the end."""
        return self.queue[0] if self.queue or self.fill() else None

    def popleft(self) -> T:
        """Take the next item; :class:`IndexError` at the end."""
        if not self.queue:
            self.fill()
        return self.queue.popleft()

    def __iter__(self) -> Iterator[T]:
        """Take every item left, as they are dealt."""
        while self.queue or self.fill():
            yield self.queue.popleft()

    def left(self) -> int:
        """How many items are left: the rest of the stream is read (not kept by this
        hand) to count them."""
        return sum(1 for _ in self)
