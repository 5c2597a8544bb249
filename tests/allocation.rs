//! An MSA leg evaluated pose after pose (a map) allocates nothing once its buffers have their size: its
//! structure is refilled in place and its condenser keeps the forest, the coordinates' order and the
//! reduced system's storage (the issue of allocation on the hot path, checked here by counting).
//! One test in this binary, counting only on its own thread.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use stiff::kinematics::frame::{Frame, Vec3};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn counted<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(true));
    let out = f();
    COUNTING.with(|c| c.set(false));
    (out, ALLOCATIONS.load(Ordering::Relaxed) - before)
}

#[test]
fn msa_legs_allocate_nothing_per_pose() {
    for (path, mode) in [
        ("manipulators/navaro2.toml", Some(1.0)),
        ("manipulators/navaro2.toml", Some(2.0)),
        ("manipulators/orthoglide-3puu-msa.toml", None),
    ] {
        let p = std::path::Path::new(path);
        let source = std::fs::read_to_string(p).unwrap();
        let overrides = mode.map(|m| [("mode".to_string(), m)].into_iter().collect()).unwrap_or_default();
        let m = stiff::model::parse_with(p, &source, &overrides, 0).unwrap().manipulator;
        let mut state = m.new_state();
        let pose = |k: usize| Frame::translation(Vec3::new(-40.0 + 4.0 * k as f64, 10.0 - 2.0 * k as f64, 0.0));
        m.unloaded(&pose(0), &mut state).unwrap();
        let (reached, allocations) = counted(|| (1..20).filter(|&k| m.unloaded(&pose(k), &mut state).is_ok()).count());
        assert_eq!(reached, 19, "{path}: every pose reachable");
        assert_eq!(allocations, 0, "{path} mode {mode:?}: allocations over 19 poses");
    }
}
