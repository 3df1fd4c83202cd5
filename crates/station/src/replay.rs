//! `spinbench replay RUN`: the raw bytes each counter module sent during a
//! run (kept in `<run>/raw/fmu-N.gz`) go through the production decoder and
//! window accumulator again; every one-second value and every point the
//! store holds must come out of them unchanged.
//!
//! bytes → frames → one-second windows (replayed) ⇒ each stored one-second
//! value is looked up, bit-exact, among the replayed windows of its module;
//! each stored point's mean is recomputed from the replayed values of its
//! dwell (`t0..t1`).

use anyhow::{Context, Result};
use spinbench_devices::capture::{read_capture, segments as capture_segments};
use spinbench_engine::StationConfig;
use spinbench_engine::config::raw_capture_file;
use spinbench_store::Store;
use spinbench_wire::fmu::{
    FrameDecoder, INSTRUMENTS_PER_MODULE, Message, WindowAccumulator, WindowConfig,
};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// What one module's capture held.
#[derive(Debug, Clone, PartialEq)]
pub struct ModuleReplay {
    /// Module number (1-based).
    pub module: usize,
    /// Bytes in the capture.
    pub bytes: u64,
    /// Valid frames decoded.
    pub frames: u64,
    /// Frames dropped for a bad CRC or tail.
    pub bad_frames: u64,
    /// Whole one-second windows re-derived.
    pub windows: usize,
    /// The capture ended without its trailer (a killed process): readable up to its last flush.
    pub cut_short: bool,
}

/// The result of a replay.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    /// Per module.
    pub modules: Vec<ModuleReplay>,
    /// One-second values in the store (with an output).
    pub values_stored: usize,
    /// Of those, found bit-exact among the replayed windows.
    pub values_matched: usize,
    /// Points in the store.
    pub points_stored: usize,
    /// Of those, whose mean the replayed values reproduce (to 1e-12 relative).
    pub points_matched: usize,
    /// Largest difference between a stored and a re-derived point mean [Hz].
    pub max_point_diff_hz: f64,
}

impl ReplayReport {
    /// True when every stored value and point came out of the raw bytes again.
    pub fn all_match(&self) -> bool {
        self.values_matched == self.values_stored && self.points_matched == self.points_stored
    }
}

/// The bit pattern of a module's outputs in one window (`None` = no value).
type WindowKey = Vec<Option<u64>>;

/// A module's replayed windows, indexed by each instrument's value.
#[derive(Default)]
struct ReplayedWindows {
    windows: Vec<WindowKey>,
    /// (instrument, value bits) → windows holding it.
    index: HashMap<(usize, u64), Vec<usize>>,
}

impl ReplayedWindows {
    fn add(&mut self, key: WindowKey) {
        let at = self.windows.len();
        for (k, bits) in key.iter().enumerate() {
            if let Some(b) = bits {
                self.index.entry((k, *b)).or_default().push(at);
            }
        }
        self.windows.push(key);
    }

    /// Is there a window with all these (instrument, value bits)?
    fn contains(&self, wanted: &[(usize, u64)]) -> bool {
        let Some(first) = wanted.first() else {
            return false;
        };
        self.index.get(first).is_some_and(|candidates| {
            candidates.iter().any(|&w| {
                wanted
                    .iter()
                    .all(|&(k, b)| self.windows[w].get(k).copied().flatten() == Some(b))
            })
        })
    }
}

/// Replay the run in `run_dir` (its id is the directory's name) against `store`.
pub fn replay(run_dir: &Path, store: &Store) -> Result<ReplayReport> {
    let run_id = run_dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .context("the run directory has no name")?;
    let station_path = run_dir.join("station.toml");
    let text = std::fs::read_to_string(&station_path).with_context(|| {
        format!(
            "{}: cannot read the run's station config",
            station_path.display()
        )
    })?;
    let station =
        StationConfig::from_toml(&text).with_context(|| station_path.display().to_string())?;
    if store.run(&run_id)?.is_none() {
        anyhow::bail!("{}: no run '{run_id}' in the store", store.target());
    }

    // Replayed windows per module: every window's dF per instrument, by bit pattern.
    let mut modules = Vec::new();
    let mut replayed: Vec<ReplayedWindows> = Vec::new();
    for (m, fmu) in station.fmu.iter().enumerate() {
        let path = run_dir
            .join(crate::run_setup::RAW_DIR)
            .join(raw_capture_file(m));
        if !path.exists() {
            anyhow::bail!(
                "{}: no raw capture for module {} (runs made before raw capture existed cannot be replayed)",
                path.display(),
                m + 1
            );
        }
        // One segment per opening (the run and each resume): each is a
        // stream of its own, decoded from a fresh decoder as the station did.
        let mut windows = ReplayedWindows::default();
        let mut module = ModuleReplay {
            module: m + 1,
            bytes: 0,
            frames: 0,
            bad_frames: 0,
            windows: 0,
            cut_short: false,
        };
        for segment in capture_segments(&path) {
            let (bytes, cut) = read_capture(&segment);
            let mut decoder = FrameDecoder::new();
            let mut accumulator = WindowAccumulator::new(WindowConfig {
                mode: fmu.mode.into(),
                reference_hz: fmu.reference_hz,
                ..WindowConfig::default()
            });
            let mut whole = 0;
            decoder.decode(&bytes, |frame| {
                let Ok(message) = Message::decode(frame) else {
                    return;
                };
                accumulator.feed(&message);
                while let Some(w) = accumulator.decode() {
                    if w.is_complete() {
                        whole += 1;
                        // The engine stores dF only from whole windows; so does the replay.
                        windows.add(
                            w.instruments
                                .iter()
                                .map(|i| i.df_hz.map(f64::to_bits))
                                .collect(),
                        );
                    }
                }
            });
            let stats = decoder.stats();
            module.bytes += bytes.len() as u64;
            module.frames += stats.frames;
            module.bad_frames += stats.bad_crc + stats.bad_tail;
            module.windows += whole;
            module.cut_short |= cut.is_some();
        }
        modules.push(module);
        replayed.push(windows);
    }

    // Stored one-second values, by time: slot → output.
    let mut by_time: BTreeMap<u64, BTreeMap<i64, f64>> = BTreeMap::new();
    for v in store.values(&run_id)? {
        if let Some(out) = v.output_hz {
            by_time
                .entry(v.t_s.to_bits())
                .or_default()
                .insert(v.slot, out);
        }
    }
    let mut values_stored = 0;
    let mut values_matched = 0;
    // (slot, time bits) → the value, for the stored values the replay reproduced.
    let mut confirmed: HashMap<(i64, u64), f64> = HashMap::new();
    for (&t, slots) in &by_time {
        for (m, windows) in replayed.iter().enumerate() {
            let first = (m * INSTRUMENTS_PER_MODULE) as i64;
            let own: Vec<(i64, f64)> = slots
                .range(first..first + INSTRUMENTS_PER_MODULE as i64)
                .map(|(&s, &v)| (s, v))
                .collect();
            if own.is_empty() {
                continue;
            }
            values_stored += own.len();
            // A window matches when every stored slot of the module has the same bits.
            let found = windows.contains(
                &own.iter()
                    .map(|&(s, v)| ((s - first) as usize, v.to_bits()))
                    .collect::<Vec<_>>(),
            );
            if found {
                values_matched += own.len();
                for (s, v) in own {
                    confirmed.insert((s, t), v);
                }
            }
        }
    }

    // Points: the mean of the confirmed values of the dwell.
    let points = store.points(&run_id)?;
    let mut points_matched = 0;
    let mut max_diff: f64 = 0.0;
    for p in &points {
        let values: Vec<f64> = by_time
            .range(p.time_s[0].to_bits()..=p.time_s[1].to_bits())
            .filter_map(|(&t, _)| confirmed.get(&(p.slot, t)).copied())
            .collect();
        if values.len() as i64 != p.n || values.is_empty() {
            continue;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let diff = (mean - p.output_hz).abs();
        max_diff = max_diff.max(diff);
        if diff <= 1e-12 * p.output_hz.abs().max(1.0) {
            points_matched += 1;
        }
    }
    Ok(ReplayReport {
        modules,
        values_stored,
        values_matched,
        points_stored: points.len(),
        points_matched,
        max_point_diff_hz: max_diff,
    })
}
