//! Stepping and resetting a vector allocates nothing, serially or on threads (a counting
//! global allocator sees every allocation of the process, workers included).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use apo_envs::{VecEnv, VecStep};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: the caller's contract is `System.alloc`'s.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: as for `dealloc`, and the caller's contract is `System.realloc`'s.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The allocations of 300 steps and a few resets of `name` × `n` on `threads` threads, after
/// a warm-up; with `must_end`, some episode must end by itself on the way.
fn allocations_of(name: &str, n: usize, threads: usize, must_end: bool) -> usize {
    let mut venv = VecEnv::make(name, n)
        .and_then(|v| v.with_threads(threads))
        .expect("threads start");
    let (obs_dim, act_dim) = (venv.obs_dim(), venv.act_dim());
    let actions: Vec<Vec<f32>> = (0..7)
        .map(|k| (0..n * act_dim).map(|i| ((i + k) % 2) as f32).collect())
        .collect();
    let mut obs = vec![0.0f32; n * obs_dim];
    let mut out = vec![VecStep::default(); n];
    let mut run = |venv: &mut VecEnv, steps: usize| {
        let mut ended = 0;
        venv.reset(Some(1), &mut obs);
        for t in 0..steps {
            venv.step(&actions[t % 7], &mut obs, &mut out);
            ended += out.iter().filter(|o| o.done()).count();
            if t % 100 == 99 {
                venv.reset(None, &mut obs);
            }
        }
        ended
    };
    run(&mut venv, 20);
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let ended = run(&mut venv, 300);
    let allocations = ALLOCATIONS.load(Ordering::SeqCst) - before;
    assert!(
        ended > 0 || !must_end,
        "{name}: no episode ended, resets untested"
    );
    allocations
}

fn allocations(name: &str, n: usize, threads: usize) -> usize {
    allocations_of(name, n, threads, true)
}

#[test]
fn steps_and_resets_allocate_nothing() {
    for threads in [1, 2, 3, 6] {
        assert_eq!(
            allocations("CartPole-v1", 6, threads),
            0,
            "{threads} threads"
        );
    }
    // MuJoCo's own allocations go through its arena, not Rust's allocator.
    for threads in [1, 2, 3] {
        assert_eq!(
            allocations("Hopper", 3, threads),
            0,
            "Hopper, {threads} threads"
        );
    }
    // GUARD (in this test, not a second one: the counter sees every thread of the process).
    // Layouts, rewards, robbers, the Drone's forces, compasses and lidars (2D and 3D); the
    // vector resets every 100 steps, so layouts are drawn again on the way.
    for name in ["Goal_Arm3", "Goal_Drone", "Push_Ant", "Chase_Point"] {
        for threads in [1, 2] {
            assert_eq!(
                allocations_of(name, 2, threads, false),
                0,
                "{name}, {threads} threads"
            );
        }
    }
}
