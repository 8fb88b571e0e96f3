//! Forward kinematics of the Gough–Stewart platform in a 1 kHz control loop: every period the
//! six leg lengths (with their rates and accelerations) computed by closed-form inverse
//! kinematics from a known platform trajectory go to the generated solver
//! (`generated::stewart`, `Solver::advance_with`), which recovers the platform's pose, velocity
//! and acceleration; the loop counts the heap allocations it makes. Run with
//! `cargo run --release -p examples --example stewart_control_loop [SECONDS]` (default 2).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use examples::stewart::{Trajectory, control};

/// Counts the allocations of this program.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract, passed on as is.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The control period (s): 1 kHz.
const PERIOD: f64 = 1e-3;

fn main() {
    let seconds = match std::env::args().nth(1).map(|s| s.parse::<f64>()) {
        None => 2.0,
        Some(Ok(s)) if s.is_finite() && s > 0.0 && s <= 3600.0 => s,
        Some(_) => {
            eprintln!("usage: stewart_control_loop [SECONDS], 0 < SECONDS ≤ 3600");
            std::process::exit(1);
        }
    };
    let periods = (seconds / PERIOD).round() as usize + 1;
    let trajectory = Trajectory::SHIPPED;
    // The solver holds Φ_q (55 × 55) and its factors: 24 KiB, kept in a box.
    let mut solver = Box::new(control::solver(&trajectory, 0.0));
    let allocations = ALLOCATIONS.load(Ordering::Relaxed);
    let start = Instant::now();
    let result = control::control_loop(&mut solver, &trajectory, periods, PERIOD);
    let elapsed = start.elapsed();
    let allocated = ALLOCATIONS.load(Ordering::Relaxed) - allocations;
    let t = match result {
        Ok(t) => t,
        Err(e) => {
            eprintln!("stopping the machine at t = {}: {e}", solver.t());
            std::process::exit(2);
        }
    };
    println!(
        "{} periods of 1 ms: {allocated} allocations, {:.2} Newton iterations and {:.1} µs per \
         period",
        t.periods,
        t.iterations as f64 / t.periods as f64,
        elapsed.as_secs_f64() * 1e6 / t.periods as f64
    );
    println!(
        "largest errors against the trajectory: position {:.1e} m, orientation {:.1e}, velocity \
         {:.1e} m/s, angular velocity {:.1e} rad/s, acceleration {:.1e} m/s², angular \
         acceleration {:.1e} rad/s²",
        t.position,
        t.rotation,
        t.velocity,
        t.angular_velocity,
        t.acceleration,
        t.angular_acceleration
    );
}
