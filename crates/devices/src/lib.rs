//! The hardware interface layer: device traits and their drivers.
//!
//! * [`Centrifuge`], [`PowerSupply`], [`CounterModule`], [`Chamber`] — what the engine
//!   asks of the hardware, in engineering units (deg/s, volts, amperes);
//! * [`DialectCentrifuge`], [`ScpiPowerSupply`], [`FmuDriver`],
//!   [`ModbusChamber`], [`LineChamber`] — drivers,
//!   each generic over its [`Transport`], so the same code talks to a real
//!   serial port, a pseudo-terminal, a TCP socket or a test [`Transcript`];
//! * [`config`] — the device sections of the station config (TOML) and
//!   `connect` functions that open a transport and build the driver;
//! * [`LineChannel`] — deadlines, retries and reconnection shared by the
//!   line-oriented drivers; [`DeviceError`] names the device and the command.
//!
//! Bytes are encoded and decoded by the `wire` crate; nothing above this
//! layer sees a byte.

pub mod capture;
pub mod centrifuge;
pub mod chamber;
pub mod config;
mod error;
pub mod fmu;
pub mod line;
pub mod outage;
pub mod psu;
pub mod transcript;
pub mod transport;

pub use centrifuge::{Centrifuge, DialectCentrifuge};
pub use chamber::{Chamber, LineChamber, ModbusChamber};
pub use error::{DeviceError, DeviceErrorKind};
pub use fmu::{CounterModule, FmuDriver, LinkStats};
pub use line::{IoPolicy, LineChannel};
pub use psu::{OutputReading, PowerSupply, ScpiPowerSupply};
pub use transcript::{Step, Transcript};
pub use transport::{SerialSettings, SerialTransport, TcpTransport, Transport};
