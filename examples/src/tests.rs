//! The example programs' cores, checked: they run, stay converged and do not allocate.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts allocations made by this test binary, in all and on the current thread.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Allocations made by this thread: the test harness's own threads (output capture,
    /// timing) allocate at moments of their own, which a global count would pick up.
    static THREAD_ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Allocations made so far by the calling thread.
fn thread_allocations() -> usize {
    THREAD_ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator unchanged; only counts calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // A const-initialised thread local needs no allocation, so this cannot recurse.
        THREAD_ALLOCATIONS.with(|c| c.set(c.get() + 1));
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

#[test]
fn the_control_loop_follows_one_crank_turn_without_allocating() {
    // One crank turn (2π/146.6 s) in 1000 periods.
    let dt = 2.0 * std::f64::consts::PI / 146.6 / 1000.0;
    let before = thread_allocations();
    let summary = crate::rssr_control_loop(1000, dt).expect("the R-S-S-R follows its crank");
    let after = thread_allocations();
    assert_eq!(after - before, 0, "the loop allocated");
    // The counters do count: one boxed value is one allocation, on this thread and in all.
    let total = ALLOCATIONS.load(Ordering::SeqCst);
    let boxed = std::hint::black_box(Box::new(1.0_f64));
    assert_eq!(thread_allocations(), after + 1, "{boxed}");
    assert!(ALLOCATIONS.load(Ordering::SeqCst) > total);
    assert_eq!(summary.periods, 1000);
    // The loop's Newton tolerance.
    assert!(summary.max_residual <= 1e-12);
    // The rocker swings, so its rate is not zero; about 1e2 rad/s at this crank speed.
    assert!(summary.max_rocker_rate > 1.0, "{summary:?}");
}

#[test]
fn the_stewart_control_loop_recovers_the_platform_at_1_khz_without_allocating() {
    use crate::stewart::{Trajectory, control};
    let trajectory = Trajectory::SHIPPED;
    // The solver holds Φ_q (55 × 55) and its factors: 24 KiB, kept off the test thread's stack.
    let mut solver = Box::new(control::solver(&trajectory, 0.0));
    let before = thread_allocations();
    let tracking = control::control_loop(&mut solver, &trajectory, 2001, 1e-3)
        .expect("the platform follows its legs");
    let after = thread_allocations();
    assert_eq!(after - before, 0, "the loop allocated");
    assert_eq!(tracking.periods, 2001);
    // The description's Newton tolerance is 1e-12 and the leg lengths' Jacobian has a
    // condition number below 4.3 along the trajectory: the 1e-10 bounds the pose
    // (measured: 9e-16 m, 1.4e-15). Velocities and accelerations solve Φ_q q̇ = ν and
    // Φ_q q̈ = γ with the exact l̇, l̈ at that pose: they err by the pose error times rates
    // below 1 per second, plus round-off (measured: 2e-16 to 8e-16), so 1e-10 holds as well.
    let t = tracking;
    for (what, error) in [
        ("position", t.position),
        ("rotation", t.rotation),
        ("velocity", t.velocity),
        ("angular velocity", t.angular_velocity),
        ("acceleration", t.acceleration),
        ("angular acceleration", t.angular_acceleration),
    ] {
        assert!(error < 1e-10, "{what}: {error:e} ({t:?})");
    }
    // The Taylor predictor starts each period within about 1e-10 of the pose (1 ms periods):
    // one Newton iteration per period, none at t = 0 (the home pose is the initial estimate).
    assert_eq!(t.iterations, 2000, "{t:?}");
}
