"""Tests of the bounded per-stream byte queue (fleet.piccolo.stream_queue)."""

from fleet.piccolo.stream_queue import StreamQueue


def test_queue_overflow_drops_oldest_and_counts() -> None:
    queue = StreamQueue()
    queue.append(bytes(4000))
    queue.append(b"\x01" * 200)
    assert len(queue) == 4096
    assert queue.overflow_bytes == 104
    assert queue.take().endswith(b"\x01" * 200)
