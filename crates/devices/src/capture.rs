//! Raw capture: the exact bytes a counter module sent, kept append-only and
//! compressed beside the run, so a whole run can be replayed through the
//! decoder (`spinbench replay`).
//!
//! [`CaptureTransport`] wraps any transport and copies every byte it reads
//! into a [`RawCapture`]: a gzip stream flushed (sync flush) at least once a
//! second, so a killed process leaves a readable file that lacks at most the
//! last second. Each opening of a run's capture writes a new segment file
//! (`fmu-1.gz`, then `fmu-1.2.gz`, … for each resume, see
//! [`RawCapture::new_segment`]), so a process killed mid-member leaves a
//! torn tail that hides nothing written after it; [`read_capture`] reads one
//! file (every member, up to a torn tail) and [`segments`] lists a capture's
//! files in order.

use crate::transport::Transport;
use flate2::Compression;
use flate2::read::MultiGzDecoder;
use flate2::write::GzEncoder;
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Most segments (openings) of one capture.
const MAX_SEGMENTS: usize = 10_000;

/// How often the compressed stream is flushed to the file.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// An append-only, compressed byte capture in one file.
pub struct RawCapture {
    encoder: GzEncoder<File>,
    last_flush: Instant,
    bytes: u64,
}

/// Segment `n` (1-based) of the capture whose first file is `first`:
/// `fmu-1.gz` → `fmu-1.gz`, `fmu-1.2.gz`, `fmu-1.3.gz`, …
pub fn segment_path(first: &Path, n: usize) -> PathBuf {
    if n <= 1 {
        return first.to_path_buf();
    }
    let name = first
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (stem, ext) = match name.strip_suffix(".gz") {
        Some(stem) => (stem.to_string(), ".gz"),
        None => (name, ""),
    };
    first.with_file_name(format!("{stem}.{n}{ext}"))
}

/// The existing segment files of the capture whose first file is `first`, in order.
pub fn segments(first: &Path) -> Vec<PathBuf> {
    (1..)
        .map(|n| segment_path(first, n))
        .take_while(|p| p.exists())
        .collect()
}

impl RawCapture {
    /// Open the next unused segment of the capture whose first file is
    /// `first` (created with its directory if needed): each opening (a
    /// new run, each resume) writes a file of its own.
    pub fn new_segment(first: &Path) -> io::Result<RawCapture> {
        if let Some(dir) = first.parent() {
            std::fs::create_dir_all(dir)?;
        }
        for n in 1..=MAX_SEGMENTS {
            let path = segment_path(first, n);
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(file) => {
                    return Ok(RawCapture {
                        encoder: GzEncoder::new(file, Compression::fast()),
                        last_flush: Instant::now(),
                        bytes: 0,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
        Err(io::Error::other(format!(
            "{}: {MAX_SEGMENTS} capture segments exist already",
            first.display()
        )))
    }

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

    fn flush_capture(&mut self) -> io::Result<()> {
        if self.failed.is_some() {
            return Ok(());
        }
        let flushed = self.capture.flush();
        if let Err(e) = &flushed {
            self.failed = Some(e.to_string());
        }
        flushed
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

    #[test]
    fn a_killed_opening_hides_nothing_of_the_next_one() {
        let dir = tempfile_dir().join("segments");
        let _ = std::fs::remove_dir_all(&dir);
        let first = dir.join("fmu-1.gz");
        let mut killed = RawCapture::new_segment(&first).expect("open");
        killed.record(b"before the kill ").expect("record");
        killed.flush().expect("flush");
        killed.record(b"never flushed").expect("record");
        std::mem::forget(killed);
        let mut resumed = RawCapture::new_segment(&first).expect("open again");
        resumed.record(b"after the resume").expect("record");
        drop(resumed);
        let files = segments(&first);
        assert_eq!(files, vec![first.clone(), dir.join("fmu-1.2.gz")]);
        let all: Vec<u8> = files.iter().flat_map(|f| read_capture(f).0).collect();
        assert_eq!(all, b"before the kill after the resume");
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
