"""A dealer reads its stream only as far as its readers ask, and gives each its items in order."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from whexar.runtime import streams
from whexar.runtime.streams import Dealer, Hand


def _counted(items: list[tuple[str, int]], read: list[int]) -> Iterator[tuple[str, int]]:
    for item in items:
        read[0] += 1
        yield item


def test_each_hand_gets_its_items_in_order_reading_only_as_far_as_asked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(streams, "BATCH", 1)
    read = [0]
    items = [("a", 1), ("b", 2), ("c", 3), ("a", 4), ("b", 5), ("a", 6)]
    dealer = Dealer(_counted(items, read))
    a, b = dealer.hand("a"), dealer.hand("b")
    assert read[0] == 0  # nothing is read before it is asked for
    assert b.peek() == 2
    assert read[0] == 2  # a's 1 is queued on the way; c has no hand and is dropped
    assert list(a.queue) == [1]
    assert a.popleft() == 1
    assert a.popleft() == 4
    assert read[0] == 4
    assert list(b.queue) == [2]  # b's next is still waiting; nothing past 4 was read
    assert list(b) == [2, 5]  # to the stream's end: a's last is queued on the way
    assert read[0] == 6
    assert list(a.queue) == [6]
    assert list(a) == [6]
    assert not a
    assert a.peek() is None
    with pytest.raises(IndexError):
        a.popleft()


def test_items_are_dealt_a_batch_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(streams, "BATCH", 3)
    read = [0]
    dealer = Dealer(_counted([("a", k) if k % 4 else ("b", k) for k in range(10)], read))
    a, b = dealer.hand("a"), dealer.hand("b")
    assert b.popleft() == 0
    assert read[0] == 3  # one batch held b's first
    assert list(a.queue) == [1, 2]
    assert b.popleft() == 4
    assert read[0] == 6
    assert [*a] == [1, 2, 3, 5, 6, 7, 9]
    assert [*b] == [8]


def test_left_counts_what_is_not_taken() -> None:
    dealer = Dealer([("a", 1), ("b", 2), ("a", 3), ("a", 4)])
    a, b = dealer.hand("a"), dealer.hand("b")
    assert a.popleft() == 1
    assert a.left() == 2
    assert b.left() == 1
    assert not a
    assert not b


def test_a_closed_dealer_reads_no_further_and_closes_its_stream(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(streams, "BATCH", 1)
    read = [0]
    items = [("a", k) for k in range(10)]
    stream = _counted(items, read)
    dealer = Dealer(stream)
    a = dealer.hand("a")
    assert a.popleft() == 0
    dealer.close()
    assert dealer.closed
    assert not a  # what was not read stays unread
    assert read[0] == 1
    with pytest.raises(StopIteration):
        next(stream)  # the generator was closed: its file would be


def test_a_hand_of_a_plain_iterable() -> None:
    hand = Hand.of(iter("xyz"))
    assert hand.peek() == "x"
    assert "".join(hand) == "xyz"
