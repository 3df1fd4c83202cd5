//! The left-over files of this station's runs (events the store did not
//! take before a run ended), written while the server runs: on a thread of
//! its own once the server listens, with progress, and again while one is
//! left, so an ended run is shown ended fleet-wide without a restart.

use super::AppState;
use anyhow::{Context, Result};
use spinbench_store::{Store, StoreTarget};
use std::sync::Arc;

/// How often a server looks again for left-over files it could not write
/// (the store down at a run's end), so an ended run is shown ended in the
/// fleet without waiting for the next start.
pub(super) const LEFT_OVER_RETRY: std::time::Duration = std::time::Duration::from_secs(30);

/// Write the left-over files of this station's runs on a thread of its own,
/// saying the progress of a backlog on standard error, and again every
/// [`LEFT_OVER_RETRY`] while one is left, until the server closes.
pub(super) fn spawn_catch_up(
    state: Arc<AppState>,
    db: StoreTarget,
    data: std::path::PathBuf,
) -> Result<std::thread::JoinHandle<()>> {
    let station = state.runner.station().0.station;
    std::thread::Builder::new()
        .name("left-over catch-up".into())
        .spawn(move || {
            let closing = state.hub.closing();
            while !*closing.borrow() {
                if !crate::recovery::left_over_files(&data).is_empty()
                    && let Ok(store) = Store::connect(&db)
                {
                    let mut said = 0;
                    let done = crate::recovery::catch_up_left_over_files(
                        &data,
                        &station,
                        &store,
                        &mut |done, of| {
                            if of > 1 && done > said {
                                eprintln!("catching up left-over files: {done} of {of} runs");
                                said = done;
                            }
                        },
                    );
                    for line in done.lines() {
                        eprintln!("{line}");
                    }
                }
                let until = std::time::Instant::now() + LEFT_OVER_RETRY;
                while std::time::Instant::now() < until && !*closing.borrow() {
                    std::thread::sleep(std::time::Duration::from_millis(200));
                }
            }
        })
        .context("cannot start the left-over catch-up thread")
}
