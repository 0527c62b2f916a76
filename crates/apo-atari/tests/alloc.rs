//! A step of `ALE/<Game>-v5` makes no Rust heap allocation: the RAM is copied into the
//! environment's own array and from there into the caller's observation buffer.
//! (The count covers the Rust side of `Env::step`, through the registry's wrappers; what the
//! ALE's C++ does inside `act` is not seen by Rust's allocator.)
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use apo_envs::{Action, Env};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

#[test]
fn stepping_allocates_nothing() {
    apo_atari::register_games().expect("registers once");
    for game in ["ALE/Pong-v5", "ALE/Breakout-v5"] {
        let mut env = apo_envs::make(game).expect(game);
        let mut obs = [0.0f32; apo_atari::RAM_SIZE];
        env.reset(Some(3), &mut obs);
        // warm up (the first frames may size internal buffers)
        for t in 0..10 {
            env.step(Action::Discrete(t % 4), &mut obs);
        }
        let before = allocations();
        let mut steps = 0;
        for t in 0..2_000 {
            let out = env.step(Action::Discrete(t % 4), &mut obs);
            steps += 1;
            if out.terminated || out.truncated {
                break;
            }
        }
        let counted = allocations() - before;
        assert_eq!(counted, 0, "{game}: {counted} allocations in {steps} steps");
        assert!(steps >= 100, "{game}: the episode ran {steps} steps");
        // and the counter does count: a heap allocation here is seen
        let before = allocations();
        let boxed = std::hint::black_box(Box::new(obs));
        assert_eq!(allocations() - before, 1);
        drop(boxed);
    }
}
