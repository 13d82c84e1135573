//! Decompression on a second thread: [`with_prefetch`] runs a reader (an inflate or zstd
//! stream) on its own thread, a few blocks ahead of the consumer, so decompressing and
//! dequantising overlap on two cores instead of taking turns on one.
//!
//! Memory stays bounded: at most [`DEPTH`] blocks wait in the channel (the producer blocks
//! when it is full), and when the consumer stops early (an error, or it has all it needs)
//! the channel closes and the producer ends at its next block.

use std::io::{self, Read};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

/// Bytes per block handed over.
const BLOCK: usize = 256 << 10;
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

/// Read `r` to its end on a second thread while `f` consumes it through a [`Prefetched`]
/// reader; returns what `f` returns. Errors of `r` reach `f` as read errors, in order.
pub(crate) fn with_prefetch<R: Read + Send, T>(
    mut r: R,
    f: impl FnOnce(&mut Prefetched) -> T,
) -> T {
    let (tx, blocks) = sync_channel::<io::Result<Vec<u8>>>(DEPTH);
    let (spare, spares) = sync_channel::<Vec<u8>>(DEPTH + 2);
    std::thread::scope(|s| {
        s.spawn(move || loop {
            let mut b = spares.try_recv().unwrap_or_default();
            b.resize(BLOCK, 0);
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
            let last = at < BLOCK || res.is_err();
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
        for n in [0, 1, BLOCK - 1, BLOCK, 3 * BLOCK + 17] {
            for fail in [false, true] {
                let got = with_prefetch(Source { at: 0, n, fail }, |r| {
                    let mut v = Vec::new();
                    let res = r.read_to_end(&mut v);
                    (v, res.is_err())
                });
                let want: Vec<u8> = (0..n).map(|i| (i % 251) as u8).collect();
                assert!(got.0 == want, "{n} bytes");
                assert_eq!(got.1, fail, "{n} bytes, fail {fail}");
            }
        }
    }

    #[test]
    fn a_consumer_that_stops_early_ends_the_producer() {
        // An endless source: the scope returns only if the producer notices the closed channel.
        let first = with_prefetch(
            Source {
                at: 0,
                n: usize::MAX,
                fail: false,
            },
            |r| {
                let mut b = [0u8; 10];
                r.read_exact(&mut b).map(|_| b[9])
            },
        );
        assert_eq!(first.ok(), Some(9));
    }
}
