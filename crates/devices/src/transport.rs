//! Byte transports with deadlines: a serial port (the serialport crate; a
//! pseudo-terminal path works the same), a TCP connection, and the
//! [`Transcript`](crate::transcript::Transcript) of tests. Drivers are
//! generic over [`Transport`], as embedded-hal drivers are over their bus.

use serde::Deserialize;
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// A bidirectional byte stream whose every call has a deadline.
pub trait Transport: Send {
    /// Where it talks to, for messages (`/dev/ttyS3`, `10.0.0.5:9878`).
    fn describe(&self) -> String;
    /// Write all of `bytes` before `deadline`.
    fn write_all(&mut self, bytes: &[u8], deadline: Instant) -> io::Result<()>;
    /// Read at least one byte into `buf`, waiting until `deadline`; a
    /// deadline with nothing read is an error of kind `TimedOut`.
    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize>;
    /// Drop input received but not yet read (a late reply to an earlier command).
    fn discard_input(&mut self) -> io::Result<()>;
    /// Close and open again, e.g. after a USB adapter disappeared and returned.
    fn reopen(&mut self) -> io::Result<()>;

    /// Put every byte read so far into the raw capture's file, where this
    /// transport keeps one (see `capture`); nothing otherwise.
    fn flush_capture(&mut self) -> io::Result<()> {
        Ok(())
    }
}

fn remaining(deadline: Instant) -> io::Result<Duration> {
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        Err(io::Error::new(io::ErrorKind::TimedOut, "deadline passed"))
    } else {
        Ok(left)
    }
}

/// Parity setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

/// Flow control setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FlowControl {
    /// None.
    #[default]
    None,
    /// XON/XOFF.
    Software,
    /// RTS/CTS.
    Hardware,
}

/// Serial port settings, as written in the station config.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSettings {
    /// Device path, e.g. `/dev/ttyS3` or a pseudo-terminal `/dev/pts/7`.
    pub path: String,
    /// Baud rate.
    pub baud: u32,
    /// Data bits, 5–8 (default 8).
    #[serde(default = "default_data_bits")]
    pub data_bits: u8,
    /// Parity (default none).
    #[serde(default)]
    pub parity: Parity,
    /// Stop bits, 1 or 2 (default 1).
    #[serde(default = "default_stop_bits")]
    pub stop_bits: u8,
    /// Flow control (default none).
    #[serde(default)]
    pub flow_control: FlowControl,
}

fn default_data_bits() -> u8 {
    8
}

fn default_stop_bits() -> u8 {
    1
}

impl SerialSettings {
    /// 8N1 at `baud` on `path`.
    pub fn new(path: impl Into<String>, baud: u32) -> Self {
        SerialSettings {
            path: path.into(),
            baud,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
            flow_control: FlowControl::None,
        }
    }

    fn builder(&self) -> io::Result<serialport::SerialPortBuilder> {
        let invalid = |what: String| io::Error::new(io::ErrorKind::InvalidInput, what);
        let data_bits = match self.data_bits {
            5 => serialport::DataBits::Five,
            6 => serialport::DataBits::Six,
            7 => serialport::DataBits::Seven,
            8 => serialport::DataBits::Eight,
            n => return Err(invalid(format!("data_bits = {n}: expected 5, 6, 7 or 8"))),
        };
        let stop_bits = match self.stop_bits {
            1 => serialport::StopBits::One,
            2 => serialport::StopBits::Two,
            n => return Err(invalid(format!("stop_bits = {n}: expected 1 or 2"))),
        };
        Ok(serialport::new(self.path.as_str(), self.baud)
            .data_bits(data_bits)
            .stop_bits(stop_bits)
            .parity(match self.parity {
                Parity::None => serialport::Parity::None,
                Parity::Even => serialport::Parity::Even,
                Parity::Odd => serialport::Parity::Odd,
            })
            .flow_control(match self.flow_control {
                FlowControl::None => serialport::FlowControl::None,
                FlowControl::Software => serialport::FlowControl::Software,
                FlowControl::Hardware => serialport::FlowControl::Hardware,
            })
            .timeout(Duration::from_millis(100)))
    }
}

/// A serial port (RS-232, RS-422 card, USB adapter or pseudo-terminal).
pub struct SerialTransport {
    settings: SerialSettings,
    port: Option<Box<dyn serialport::SerialPort>>,
}

impl SerialTransport {
    /// Open the port described by `settings`.
    pub fn open(settings: SerialSettings) -> io::Result<Self> {
        let mut t = SerialTransport {
            settings,
            port: None,
        };
        t.reopen()?;
        Ok(t)
    }

    fn port(&mut self) -> io::Result<&mut Box<dyn serialport::SerialPort>> {
        self.port
            .as_mut()
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotConnected, "the port is closed"))
    }
}

fn serial_error(e: serialport::Error) -> io::Error {
    io::Error::other(e.to_string())
}

impl Transport for SerialTransport {
    fn describe(&self) -> String {
        format!("{} at {} baud", self.settings.path, self.settings.baud)
    }

    fn write_all(&mut self, bytes: &[u8], deadline: Instant) -> io::Result<()> {
        let port = self.port()?;
        port.set_timeout(remaining(deadline)?)
            .map_err(serial_error)?;
        port.write_all(bytes)?;
        port.flush()
    }

    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        let left = remaining(deadline)?;
        let port = self.port()?;
        port.set_timeout(left).map_err(serial_error)?;
        match port.read(buf) {
            // A serial read of 0 bytes is a timeout, not an end of stream.
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no bytes before the deadline",
            )),
            other => other,
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.port()?
            .clear(serialport::ClearBuffer::Input)
            .map_err(serial_error)
    }

    fn reopen(&mut self) -> io::Result<()> {
        self.port = None;
        let port = self.settings.builder()?.open().map_err(|e| {
            io::Error::other(format!(
                "cannot open serial port {}: {e}",
                self.settings.path
            ))
        })?;
        self.port = Some(port);
        Ok(())
    }
}

/// A TCP connection (controllers on Ethernet, SCPI supplies on port 5025).
pub struct TcpTransport {
    address: String,
    connect_timeout: Duration,
    stream: Option<TcpStream>,
}

impl TcpTransport {
    /// Connect to `address` (`host:port`).
    pub fn connect(address: impl Into<String>, connect_timeout: Duration) -> io::Result<Self> {
        let mut t = TcpTransport {
            address: address.into(),
            connect_timeout,
            stream: None,
        };
        t.reopen()?;
        Ok(t)
    }

    fn stream(&mut self) -> io::Result<&mut TcpStream> {
        self.stream
            .as_mut()
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotConnected, "not connected"))
    }
}

impl Transport for TcpTransport {
    fn describe(&self) -> String {
        self.address.clone()
    }

    fn write_all(&mut self, bytes: &[u8], deadline: Instant) -> io::Result<()> {
        let left = remaining(deadline)?;
        let stream = self.stream()?;
        stream.set_write_timeout(Some(left))?;
        stream.write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], deadline: Instant) -> io::Result<usize> {
        let left = remaining(deadline)?;
        let stream = self.stream()?;
        stream.set_read_timeout(Some(left))?;
        match stream.read(buf) {
            Ok(0) => {
                self.stream = None;
                Err(io::Error::new(
                    io::ErrorKind::ConnectionAborted,
                    "the peer closed the connection",
                ))
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock) => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no bytes before the deadline",
            )),
            other => other,
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let stream = self.stream()?;
        stream.set_nonblocking(true)?;
        let mut scratch = [0u8; 1024];
        let result = loop {
            match stream.read(&mut scratch) {
                Ok(0) => break Ok(()),
                Ok(_) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(()),
                Err(e) => break Err(e),
            }
        };
        stream.set_nonblocking(false)?;
        result
    }

    fn reopen(&mut self) -> io::Result<()> {
        self.stream = None;
        let mut last = io::Error::new(
            io::ErrorKind::NotFound,
            format!("{} resolves to no address", self.address),
        );
        for addr in self.address.to_socket_addrs()? {
            match TcpStream::connect_timeout(&addr, self.connect_timeout) {
                Ok(s) => {
                    s.set_nodelay(true)?;
                    self.stream = Some(s);
                    return Ok(());
                }
                Err(e) => last = e,
            }
        }
        Err(last)
    }
}
