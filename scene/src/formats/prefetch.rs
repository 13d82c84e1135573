//! Decompression on a second thread: [`with_prefetch`] runs a reader (an inflate or zstd
//! stream) on its own thread, a few blocks ahead of the consumer, so decompressing and
//! dequantising overlap on two cores instead of taking turns on one.
//!
//! Memory stays bounded: at most [`DEPTH`] blocks wait in the channel (the producer blocks
//! when it is full), and when the consumer stops early (an error, or it has all it needs)
//! the channel closes and the producer ends at its next block.

use std::io::{self, Read};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

/// Bytes per block handed over, at most: large enough that per-block costs vanish, and
/// L2-sized. Small streams use smaller blocks ([`block_for`]).
const BLOCK: usize = 256 << 10;

/// The smallest block: per-block costs (a channel send, a wake-up) stay far below the time
/// to inflate 16 KiB.
const MIN_BLOCK: usize = 16 << 10;

/// The block size for a stream of about `bytes`: a 32nd of it within [16 KiB, 256 KiB], so
/// the blocks in flight (up to `DEPTH + 3`, see [`with_prefetch`]) stay a small fraction of a
/// small file's data too. With fixed 256 KiB blocks they were 1.3 MB, a fifth of a 113k-Gaussian
/// SH-0 cloud.
pub(crate) fn block_for(bytes: u64) -> usize {
    (bytes / 32).clamp(MIN_BLOCK as u64, BLOCK as u64) as usize
}
/// Blocks in flight between the threads.
const DEPTH: usize = 2;

/// The consumer's side: a [`Read`] over the blocks the producer sends.
pub(crate) struct Prefetched {
    blocks: Receiver<io::Result<Vec<u8>>>,
    /// Emptied blocks go back to the producer for reuse.
    spare: SyncSender<Vec<u8>>,
    cur: Vec<u8>,
    at: usize,
    done: bool,
}

impl Read for Prefetched {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.at == self.cur.len() {
            if self.done {
                return Ok(0);
            }
            match self.blocks.recv() {
                Ok(Ok(b)) => {
                    let old = std::mem::replace(&mut self.cur, b);
                    // The producer may have ended; a spare it never takes is simply dropped.
                    let _ = self.spare.try_send(old);
                    self.at = 0;
                }
                Ok(Err(e)) => {
                    self.done = true;
                    return Err(e);
                }
                // The producer ended: end of stream.
                Err(_) => self.done = true,
            }
        }
        let k = buf.len().min(self.cur.len() - self.at);
        buf[..k].copy_from_slice(&self.cur[self.at..self.at + k]);
        self.at += k;
        Ok(k)
    }
}

/// Streams smaller than this are read on the calling thread: they inflate in a few
/// milliseconds, and a second thread costs more than its overlap saves in memory (its stack and
/// its own malloc arena, about 1–2 MB of resident memory next to a 6 MB cloud), not in time.
pub(crate) const SEQUENTIAL_BELOW: u64 = 4 << 20;

/// Read `r` (a stream of about `bytes` bytes) to its end on a second thread while `f`
/// consumes it; returns what `f` returns. Errors of `r` reach `f` as read errors, in order.
/// Below [`SEQUENTIAL_BELOW`] bytes, `f` reads `r` directly.
pub(crate) fn with_prefetch<R: Read + Send, T>(
    mut r: R,
    bytes: u64,
    f: impl FnOnce(&mut dyn Read) -> T,
) -> T {
    if bytes < SEQUENTIAL_BELOW {
        return f(&mut r);
    }
    prefetch_blocks(r, block_for(bytes), f)
}

/// [`with_prefetch`] on a second thread, in blocks of `block` bytes.
fn prefetch_blocks<R: Read + Send, T>(
    mut r: R,
    block: usize,
    f: impl FnOnce(&mut dyn Read) -> T,
) -> T {
    let block = block.clamp(1, BLOCK);
    let (tx, blocks) = sync_channel::<io::Result<Vec<u8>>>(DEPTH);
    let (spare, spares) = sync_channel::<Vec<u8>>(DEPTH + 2);
    std::thread::scope(|s| {
        s.spawn(move || loop {
            let mut b = spares.try_recv().unwrap_or_default();
            b.resize(block, 0);
            let mut at = 0;
            let res = loop {
                if at == b.len() {
                    break Ok(());
                }
                match r.read(&mut b[at..]) {
                    Ok(0) => break Ok(()),
                    Ok(k) => at += k,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => break Err(e),
                }
            };
            b.truncate(at);
            let last = at < block || res.is_err();
            if at > 0 && tx.send(Ok(b)).is_err() {
                return;
            }
            if let Err(e) = res {
                let _ = tx.send(Err(e));
            }
            if last {
                return;
            }
        });
        let mut reader = Prefetched {
            blocks,
            spare,
            cur: Vec::new(),
            at: 0,
            done: false,
        };
        let out = f(&mut reader);
        // Closing the channel ends the producer at its next send.
        drop(reader);
        out
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader of `n` bytes (i mod 251) in pieces of at most 1000 bytes, failing at the end
    /// when `fail`.
    struct Source {
        at: usize,
        n: usize,
        fail: bool,
    }
    impl Read for Source {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.at == self.n {
                return if self.fail {
                    Err(io::Error::other("broken"))
                } else {
                    Ok(0)
                };
            }
            let k = buf.len().min(self.n - self.at).min(1000);
            for (j, b) in buf[..k].iter_mut().enumerate() {
                *b = ((self.at + j) % 251) as u8;
            }
            self.at += k;
            Ok(k)
        }
    }

    #[test]
    fn passes_every_byte_in_order_then_the_error() {
        for (n, block) in [0, 1, BLOCK - 1, BLOCK, 3 * BLOCK + 17]
            .into_iter()
            .flat_map(|n| [(n, BLOCK), (n, MIN_BLOCK), (n, 1000)])
        {
            for fail in [false, true] {
                let got = prefetch_blocks(Source { at: 0, n, fail }, block, |r| {
                    let mut v = Vec::new();
                    let res = r.read_to_end(&mut v);
                    (v, res.is_err())
                });
                let want: Vec<u8> = (0..n).map(|i| (i % 251) as u8).collect();
                assert!(got.0 == want, "{n} bytes in blocks of {block}");
                assert_eq!(got.1, fail, "{n} bytes, blocks of {block}, fail {fail}");
            }
        }
    }

    #[test]
    fn a_consumer_that_stops_early_ends_the_producer() {
        // An endless source: the scope returns only if the producer notices the closed channel.
        let first = prefetch_blocks(
            Source {
                at: 0,
                n: usize::MAX,
                fail: false,
            },
            MIN_BLOCK,
            |r| {
                let mut b = [0u8; 10];
                r.read_exact(&mut b).map(|_| b[9])
            },
        );
        assert_eq!(first.ok(), Some(9));
    }
}
