"""The chunks an output bag closes, compressed and handed back to be written in order.

A chunk is compressed on a worker thread (zstd and LZ4 release the GIL) while the next one is
built, and written by the calling thread once that one closes: in order, and at most
:data:`COMPRESSING` chunks in flight, so memory stays flat. Without the thread (an output split
by size or duration needs each file's size before the next chunk) a chunk is compressed as it
closes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

from bagkit.bag.mcapio.chunk_builder import ChunkBuilder, ClosedChunk, Compress

# Chunks closed and not yet written: one being compressed, one waiting its turn. A rewritten
# input chunk often closes two output chunks in a row; with one in flight the calling thread
# waits for the first one's compression before it goes on (benchmarks/README.md, sixth pass).
COMPRESSING = 2


class ChunkCompression:
    """Closes chunks with ``compression`` and passes them to ``write`` in the order they came.

    Args:
        compression: the chunks' compression name in MCAP (``""``: none).
        compress: its function (:func:`~bagkit.bag.bag_files.compressor`).
        write: writes one closed chunk, always on the calling thread.
        threaded: compress on a worker thread (when there is compression at all).
    """

    def __init__(
        self,
        compression: str,
        compress: Compress,
        write: Callable[[ClosedChunk], None],
        *,
        threaded: bool,
    ) -> None:
        self.compression = compression
        self._compress = compress
        self._write = write
        # One worker: it owns the compressor (zstd's is not thread-safe) and keeps the order.
        threaded = threaded and bool(compression)
        self._worker = ThreadPoolExecutor(1, "bagkit-compress") if threaded else None
        self._closing: deque[Future[ClosedChunk]] = deque()  # in the order they are written

    def add(self, chunk: ChunkBuilder) -> None:
        """Close ``chunk``; write it now, or once :data:`COMPRESSING` more are in flight."""
        if self._worker is None:
            self._write(chunk.close(self.compression, self._compress))
            return
        self._closing.append(self._worker.submit(chunk.close, self.compression, self._compress))
        self.flush(COMPRESSING)

    def flush(self, waiting: int = 0) -> None:
        """Write the chunks compressed on the worker, in order, until ``waiting`` are left."""
        while len(self._closing) > waiting:
            self._write(self._closing.popleft().result())

    def stop(self, *, discard: bool = False) -> None:
        """Let the worker finish the chunk it holds (the others are cancelled) and end;
        ``discard``: drop the chunks not written (an aborted output)."""
        if discard:
            self._closing.clear()
        if self._worker is not None:
            self._worker.shutdown(cancel_futures=True)
            self._worker = None
