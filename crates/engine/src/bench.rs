//! The hardware of a station, as the engine sees it: the device traits.

use spinbench_devices::{Centrifuge, Chamber, CounterModule, PowerSupply};

/// The hardware of a station.
pub struct Bench {
    /// The centrifuge.
    pub centrifuge: Box<dyn Centrifuge>,
    /// The counter modules, in slot order.
    pub modules: Vec<Box<dyn CounterModule>>,
    /// The instruments' ±15 V supply (outputs 1 and 2).
    pub instrument_supply: Box<dyn PowerSupply>,
    /// The modules' supply, if the station switches it.
    pub module_supply: Option<Box<dyn PowerSupply>>,
    /// The temperature chamber, if the station has one.
    pub chamber: Option<Box<dyn Chamber>>,
}
