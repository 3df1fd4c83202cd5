//! The bench's clock: in real time (or faster), or in lockstep with the
//! station (virtual time).

use super::{
    Arc, AtomicBool, Duration, Instant, JoinHandle, LOCKSTEP_CLOCK_PERIOD, LOCKSTEP_LIVENESS,
    MODULE_BUFFER_LIMIT, Ordering, ServeStats, Shared, TICK_S, VecDeque, World, lock, thread,
};

pub(super) fn run_clock(
    world: Shared<World>,
    buffers: Vec<Shared<VecDeque<u8>>>,
    speed: f64,
    stop: Arc<AtomicBool>,
    stats: Arc<ServeStats>,
) -> JoinHandle<()> {
    thread::spawn(move || {
        if speed == 0.0 {
            lockstep_clock(&world, &buffers, &stop);
            return;
        }
        let start = Instant::now();
        let mut ticks_done: u64 = 0;
        while !stop.load(Ordering::Relaxed) {
            let due = (start.elapsed().as_secs_f64() * speed / TICK_S) as u64;
            let mut stepped = 0;
            while ticks_done < due && stepped < 400 {
                let out = lock(&world).step();
                for (bytes, buffer) in out.iter().zip(&buffers) {
                    let mut b = lock(buffer);
                    if b.len() > MODULE_BUFFER_LIMIT {
                        stats
                            .overrun_bytes
                            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                    } else {
                        b.extend(bytes);
                    }
                }
                ticks_done += 1;
                stepped += 1;
            }
            thread::sleep(Duration::from_millis(1));
        }
    })
}

/// The clock of virtual time. The world moves on the station's steps (see
/// [`crate::world`]); this thread only runs it in real time while it is
/// free-running (after a run: a table left spinning must slow down), and
/// keeps a station that never polls the rate fed ([`LOCKSTEP_LIVENESS`]).
pub(super) fn lockstep_clock(
    world: &Shared<World>,
    buffers: &[Shared<VecDeque<u8>>],
    stop: &AtomicBool,
) {
    let mut free: Option<(Instant, u64)> = None;
    let mut last_second = (0u64, Instant::now());
    while !stop.load(Ordering::Relaxed) {
        {
            let mut w = lock(world);
            if w.free_running() {
                let (since, done) = free.get_or_insert_with(|| (Instant::now(), 0));
                let due = (since.elapsed().as_secs_f64() / TICK_S) as u64;
                let mut stepped = 0;
                while *done < due && stepped < 400 {
                    // Nothing streams: the bytes are empty.
                    let _ = w.step();
                    *done += 1;
                    stepped += 1;
                }
            } else {
                free = None;
                let seconds = w.seconds_produced();
                if seconds != last_second.0 {
                    last_second = (seconds, Instant::now());
                } else if w.streaming_any()
                    && w.outbox_empty()
                    && last_second.1.elapsed() > LOCKSTEP_LIVENESS
                    && buffers.iter().all(|b| lock(b).is_empty())
                {
                    w.advance_second();
                }
            }
        }
        // Nothing here needs to be quick: the station's own steps move the
        // world; this thread only paces real time after a run and liveness.
        thread::sleep(LOCKSTEP_CLOCK_PERIOD);
    }
}
