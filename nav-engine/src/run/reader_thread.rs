//! Reading and parsing on a thread of their own, for the files `host-sim run` streams (the
//! IMU file, [`super::execute::threaded_file_reader`]; the truth file,
//! [`super::truth::TruthFile::records`]): the records are handed over in chunks through a
//! bounded channel, so parsing overlaps the filter with a fixed number of records in flight.

/// The items of the reader `open` returns, read on a thread named `name` and handed over in
/// chunks of `chunk` items through a channel holding `queue` chunks: at most `queue + 2`
/// chunks exist at once (the queued ones, the one being filled, the one being consumed). The
/// thread stops at its first error, passed on after the items before it, or when the
/// returned iterator is dropped. When the thread cannot be started, the one item is the
/// error `spawn_failed` makes of the reason.
pub(crate) fn read_in_chunks<T, E, I>(
    name: &str,
    chunk: usize,
    queue: usize,
    open: impl FnOnce() -> Result<I, E> + Send + 'static,
    spawn_failed: impl FnOnce(std::io::Error) -> E,
) -> impl Iterator<Item = Result<T, E>>
where
    T: Send + 'static,
    E: Send + 'static,
    I: Iterator<Item = Result<T, E>>,
{
    let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Vec<T>, E>>(queue);
    let spawned = std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let rd = match open() {
                Ok(r) => r,
                Err(e) => {
                    let _ = tx.send(Err(e));
                    return;
                }
            };
            let mut buf = Vec::with_capacity(chunk);
            for r in rd {
                match r {
                    Ok(x) => {
                        buf.push(x);
                        if buf.len() == chunk {
                            let full = std::mem::replace(&mut buf, Vec::with_capacity(chunk));
                            if tx.send(Ok(full)).is_err() {
                                return;
                            }
                        }
                    }
                    Err(e) => {
                        if !buf.is_empty() {
                            let _ = tx.send(Ok(std::mem::take(&mut buf)));
                        }
                        let _ = tx.send(Err(e));
                        return;
                    }
                }
            }
            if !buf.is_empty() {
                let _ = tx.send(Ok(buf));
            }
        });
    // a thread that did not start dropped its sender: the channel is empty and closed
    Chunks {
        failed: spawned.err().map(spawn_failed),
        rx,
        items: Vec::new().into_iter(),
        err: None,
    }
}

/// The consumer's side of [`read_in_chunks`]: the items of the chunk at hand, then the next
/// chunk's, and an error after the items before it (one branch per item in the common case).
struct Chunks<T, E> {
    /// The thread could not be started: this error first (and then nothing).
    failed: Option<E>,
    rx: std::sync::mpsc::Receiver<Result<Vec<T>, E>>,
    /// The chunk being consumed.
    items: std::vec::IntoIter<T>,
    /// The error received, passed on once the items before it are.
    err: Option<E>,
}

impl<T, E> Iterator for Chunks<T, E> {
    type Item = Result<T, E>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(x) = self.items.next() {
                return Some(Ok(x));
            }
            if let Some(e) = self.failed.take().or_else(|| self.err.take()) {
                return Some(Err(e));
            }
            match self.rx.recv().ok()? {
                Ok(v) => self.items = v.into_iter(),
                Err(e) => self.err = Some(e),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::read_in_chunks;

    /// The items come in order across chunk boundaries, an error after the items before it
    /// and then nothing; a source that cannot be opened gives its error alone.
    #[test]
    fn items_then_the_error_then_nothing() {
        for n in [0usize, 1, 2, 3, 7, 9] {
            let it = read_in_chunks(
                "t",
                3,
                1,
                move || {
                    let v: Vec<Result<usize, String>> = (0..n)
                        .map(Ok)
                        .chain(std::iter::once(Err("bad".to_string())))
                        .collect();
                    Ok::<_, String>(v.into_iter())
                },
                |e| e.to_string(),
            );
            let got: Vec<Result<usize, String>> = it.collect();
            let want: Vec<Result<usize, String>> = (0..n)
                .map(Ok)
                .chain(std::iter::once(Err("bad".to_string())))
                .collect();
            assert_eq!(got, want, "{n} items");
        }
        let failed: Vec<Result<usize, String>> = read_in_chunks(
            "t",
            3,
            1,
            || Err::<std::vec::IntoIter<Result<usize, String>>, _>("no file".to_string()),
            |e| e.to_string(),
        )
        .collect();
        assert_eq!(failed, vec![Err("no file".to_string())]);
        let whole: Vec<Result<usize, String>> = read_in_chunks(
            "t",
            4,
            2,
            || Ok::<_, String>((0..10).map(Ok).collect::<Vec<_>>().into_iter()),
            |e| e.to_string(),
        )
        .collect();
        assert_eq!(whole, (0..10).map(Ok).collect::<Vec<_>>());
    }
}
