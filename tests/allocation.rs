//! An MSA leg evaluated pose after pose (a map) allocates nothing once its buffers have their size: its
//! structure is refilled in place and its condenser keeps the forest, the coordinates' order and the
//! reduced system's storage (the issue of allocation on the hot path, checked here by counting); so does a
//! VJM manipulator's loaded equilibrium. Each test counts only the allocations made on its own thread.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use stiff::kinematics::frame::{apply_twist, Frame, Vec3, Vec6};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
    /// Bytes allocated minus bytes freed on this thread while it counts, and the largest that reached.
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

/// Counts an allocation (or a change of size, `grown` bytes) made while its thread counts.
fn count(grown: isize) {
    if COUNTING.with(Cell::get) {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        resize(grown);
    }
}

/// Follows the live bytes of a counting thread.
fn resize(grown: isize) {
    if COUNTING.with(Cell::get) {
        let live = LIVE.with(|l| {
            l.set(l.get() + grown);
            l.get()
        });
        PEAK.with(|p| p.set(p.get().max(live)));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size() as isize);
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        resize(-(layout.size() as isize));
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(new_size as isize - layout.size() as isize);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The largest number of bytes `f` held allocated at once (on this thread, beyond what it was given).
fn peak_bytes<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LIVE.with(|l| l.set(0));
    PEAK.with(|p| p.set(0));
    let (out, _) = counted(f);
    (out, PEAK.with(Cell::get).max(0) as usize)
}

fn counted<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = ALLOCATIONS.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    let out = f();
    COUNTING.with(|c| c.set(false));
    (out, ALLOCATIONS.with(Cell::get) - before)
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

/// The loaded equilibrium of a VJM manipulator (paper 000 eq 73-75: Newton on the platform pose and every
/// leg's configuration and end wrench) is linearised, factorised and solved several times per point; once
/// its buffers have their size, a point warm-started from its neighbour allocates nothing.
#[test]
fn loaded_vjm_deflections_allocate_nothing_per_point() {
    let p = std::path::Path::new("manipulators/orthoglide-3puu.toml");
    let source = std::fs::read_to_string(p).unwrap();
    let m = stiff::model::parse_with(p, &source, &Default::default(), 0).unwrap().manipulator;
    let mut state = m.new_state();
    let wrench = Vec6::new(115.47, 115.47, 115.47, 0.0, 0.0, 0.0);
    let pose = |k: usize| Frame::translation(Vec3::new(-40.0 + 4.0 * k as f64, 10.0 - 2.0 * k as f64, 5.0));
    m.place(&pose(0), &mut state).unwrap();
    let mut last = m.deflect(&pose(0), &wrench, None, &mut state).unwrap();
    let (solved, allocations) = counted(|| {
        (1..20)
            .filter(|&k| {
                m.place(&pose(k), &mut state).unwrap();
                // The neighbour's displacement as the start, as a map's warm start makes it.
                let start = apply_twist(&pose(k), &last.displacement);
                match m.deflect(&pose(k), &wrench, Some(&start), &mut state) {
                    Ok(d) => {
                        last = d;
                        true
                    }
                    Err(_) => false,
                }
            })
            .count()
    });
    assert_eq!(solved, 19, "every point solved");
    assert_eq!(allocations, 0, "allocations over 19 loaded points");
}

/// Regression: drawing a map over one section of 1,000 x 1,000 points took 248 MB, 250 bytes per point:
/// every column read was copied several times over (positions, the rows drawn, their coordinates, every
/// value kept as a candidate extreme, each name as its own string). The picture needs memory in proportion
/// to what it draws: here under 130 bytes per point of a 400 x 400 section (the four columns kept, 8 bytes per
/// number and per name, and the value drawn), whatever the number of columns the file has.
#[test]
fn drawing_a_large_section_needs_memory_in_proportion_to_the_points_drawn() {
    use std::fmt::Write as _;
    let n = 400;
    let mut csv = String::from("index,name,x_mm,y_mm,z_mm,status,rank,condition,c_tran_max_mm_per_N");
    (0..24).for_each(|k| write!(csv, ",extra{k}_mm").unwrap());
    csv.push('\n');
    for i in 0..n * n {
        let (x, y) = ((i % n) as f64 - 150.0, (i / n) as f64 - 150.0);
        let value = 1e-4 * (1.0 + 0.5 * (0.01 * x).sin() * (0.02 * y).cos());
        write!(csv, "{i},,{x},{y},0,ok,6,12.5,{value}").unwrap();
        (0..24).for_each(|k| write!(csv, ",{}", k as f64 * 0.125).unwrap());
        csv.push('\n');
    }
    let (svg, peak) = peak_bytes(|| stiff::plot::plot_text(&csv, &Default::default()).unwrap());
    assert!(svg.contains("<image"), "drawn as a raster");
    let per_point = peak as f64 / (n * n) as f64;
    assert!(per_point < 130.0, "{per_point:.0} bytes per point drawn ({peak} bytes)");
}
