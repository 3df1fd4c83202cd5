//! Raw capture: the exact bytes a counter module sent, kept append-only and
//! compressed beside the run, so a whole run can be replayed through the
//! decoder (`spinbench replay`).
//!
//! [`CaptureTransport`] wraps any transport and copies every byte it reads
//! into a [`RawCapture`]: a gzip stream flushed (sync flush) at least once a
//! second, so a killed process leaves a readable file that lacks at most the
//! last second. Each opening appends a new gzip member (a resumed run adds to
//! the same file); [`read_capture`] reads every member in turn.

use crate::transport::Transport;
use flate2::Compression;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

/// How often the compressed stream is flushed to the file.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// An append-only, compressed byte capture in one file.
pub struct RawCapture {
    encoder: GzEncoder<File>,
    last_flush: Instant,
    bytes: u64,
}

impl RawCapture {
    /// Open `path` for appending (created with its directory if needed).
    pub fn append(path: &Path) -> io::Result<RawCapture> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        let file = OpenOptions::new().create(true).append(true).open(path)?;
        Ok(RawCapture {
            // Fast compression: the capture runs beside the measurement.
            encoder: GzEncoder::new(file, Compression::fast()),
            last_flush: Instant::now(),
            bytes: 0,
        })
    }

    /// Append bytes; flushes when a second has passed since the last flush.
    pub fn record(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.encoder.write_all(bytes)?;
        self.bytes += bytes.len() as u64;
        if self.last_flush.elapsed() >= FLUSH_EVERY {
            self.flush()?;
        }
        Ok(())
    }

    /// Flush everything recorded so far to the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.encoder.flush()?;
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Bytes recorded (uncompressed) since it was opened.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl Drop for RawCapture {
    fn drop(&mut self) {
        // Finish the gzip member (its trailer) when the run ends normally.
        let _ = self.encoder.try_finish();
    }
}

/// A transport that records every byte it reads.
pub struct CaptureTransport<T: Transport> {
    inner: T,
    capture: RawCapture,
    /// The first capture error, reported once: losing the capture must not
    /// stop the measurement (the store keeps the one-second values).
    failed: Option<String>,
}

impl<T: Transport> CaptureTransport<T> {
    /// Wrap `inner`, recording into `capture`.
    pub fn new(inner: T, capture: RawCapture) -> Self {
        CaptureTransport {
            inner,
            capture,
            failed: None,
        }
    }

    /// Why the capture stopped, if it did.
    pub fn failure(&self) -> Option<&str> {
        self.failed.as_deref()
    }
}

impl<T: Transport> Transport for CaptureTransport<T> {
    fn describe(&self) -> String {
        self.inner.describe()
    }

    fn write_all(&mut self, bytes: &[u8], deadline: Instant) -> io::Result<()> {
        self.inner.write_all(bytes, deadline)
    }

    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        let n = self.inner.read(buf, deadline)?;
        if self.failed.is_none()
            && let Err(e) = self.capture.record(&buf[..n])
        {
            self.failed = Some(e.to_string());
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.inner.discard_input()
    }

    fn reopen(&mut self) -> io::Result<()> {
        self.inner.reopen()
    }
}

/// Read a whole capture file (every gzip member, in order). A file cut
/// short by a killed process yields what was flushed, and the error.
pub fn read_capture(path: &Path) -> (Vec<u8>, Option<io::Error>) {
    let mut out = Vec::new();
    let file = match File::open(path) {
        Ok(f) => f,
        Err(e) => return (out, Some(e)),
    };
    let mut decoder = MultiGzDecoder::new(file);
    let mut chunk = [0u8; 64 * 1024];
    loop {
        match decoder.read(&mut chunk) {
            Ok(0) => return (out, None),
            Ok(n) => out.extend_from_slice(&chunk[..n]),
            Err(e) => return (out, Some(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transcript::{Step, Transcript};

    #[test]
    fn every_byte_read_is_captured_and_appended_runs_read_back_in_order() {
        let dir = tempfile_dir();
        let path = dir.join("fmu-1.gz");
        for part in [&b"first run "[..], &b"and the resumed one"[..]] {
            let transcript = Transcript::new(vec![Step::Reply(part.to_vec())]);
            let mut t = CaptureTransport::new(transcript, RawCapture::append(&path).expect("open"));
            let mut buf = [0u8; 64];
            let n = t
                .read(&mut buf, Instant::now() + Duration::from_secs(1))
                .expect("read");
            assert_eq!(&buf[..n], part);
            assert!(t.failure().is_none());
        }
        let (bytes, err) = read_capture(&path);
        assert!(err.is_none(), "{err:?}");
        assert_eq!(bytes, b"first run and the resumed one");
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn a_capture_cut_short_yields_what_was_flushed() {
        let dir = tempfile_dir();
        let path = dir.join("cut.gz");
        let mut c = RawCapture::append(&path).expect("open");
        c.record(b"flushed bytes").expect("record");
        c.flush().expect("flush");
        // A killed process never writes the trailer.
        std::mem::forget(c);
        let (bytes, _) = read_capture(&path);
        assert_eq!(bytes, b"flushed bytes");
        let _ = std::fs::remove_dir_all(dir);
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "spinbench-capture-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::create_dir_all(&dir);
        dir
    }
}
