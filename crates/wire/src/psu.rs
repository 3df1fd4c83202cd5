//! SCPI commands of a programmable DC supply (IEEE 488.2; method.md §4):
//! `*IDN?`, channel selection, voltage and current limit, output on/off,
//! measurements and the error queue. The same lines work over a USB virtual
//! serial port or TCP port 5025.

use crate::scpi;

/// An operation on a power supply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PsuRequest {
    /// `*IDN?`
    Identify,
    /// `*CLS`: clear the status and error queue.
    ClearStatus,
    /// `INST:NSEL <n>`: address channel n (1-based) with the following commands.
    SelectChannel(u8),
    /// `VOLT <V>`
    SetVoltage(f64),
    /// `CURR <A>`: the current limit.
    SetCurrentLimit(f64),
    /// `OUTP ON|OFF`
    Output(bool),
    /// `MEAS:VOLT?`
    MeasureVoltage,
    /// `MEAS:CURR?`
    MeasureCurrent,
    /// `SYST:ERR?`: the oldest error-queue entry.
    ReadError,
}

impl PsuRequest {
    /// The command line (without terminator).
    pub fn line(&self) -> String {
        match self {
            PsuRequest::Identify => "*IDN?".into(),
            PsuRequest::ClearStatus => "*CLS".into(),
            PsuRequest::SelectChannel(n) => format!("INST:NSEL {n}"),
            PsuRequest::SetVoltage(v) => format!("VOLT {}", scpi::format_number(*v)),
            PsuRequest::SetCurrentLimit(a) => format!("CURR {}", scpi::format_number(*a)),
            PsuRequest::Output(on) => format!("OUTP {}", if *on { "ON" } else { "OFF" }),
            PsuRequest::MeasureVoltage => "MEAS:VOLT?".into(),
            PsuRequest::MeasureCurrent => "MEAS:CURR?".into(),
            PsuRequest::ReadError => "SYST:ERR?".into(),
        }
    }

    /// True if the supply answers this line.
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            PsuRequest::Identify
                | PsuRequest::MeasureVoltage
                | PsuRequest::MeasureCurrent
                | PsuRequest::ReadError
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scpi::{HeaderSpec, parse_line};

    #[test]
    fn lines_are_standard_scpi() {
        assert_eq!(PsuRequest::SetVoltage(15.0).line(), "VOLT 15");
        assert_eq!(PsuRequest::SetCurrentLimit(0.35).line(), "CURR 0.35");
        assert_eq!(PsuRequest::Output(false).line(), "OUTP OFF");
        assert_eq!(PsuRequest::SelectChannel(2).line(), "INST:NSEL 2");
        assert!(PsuRequest::MeasureCurrent.is_query());
        assert!(!PsuRequest::Output(true).is_query());
        // The short forms the driver sends are accepted by the long-form spec.
        let cmd = parse_line(&PsuRequest::MeasureCurrent.line()).expect("parses");
        assert!(HeaderSpec::new("MEASure:CURRent?").matches(&cmd));
    }
}
