//! Compensation latency along a finely sampled tool path, one target after the other as a controller would
//! step (`stiff::study::compensate::Compensator`): the Orthoglide 3-PUU milling from Q2 to Q5 (paper 000
//! s. 5.2) under the cutting wrench with the Case B leg errors. Prints targets per second on one core (over
//! the whole run, and over its fastest 10,000 consecutive targets: on a shared machine the run's rate
//! measures the neighbours too), the latency per target (median, 99th percentile, largest), commands tried
//! after the mirror command and loaded equilibria per target: with the full rows, then with only what a
//! controller needs (`commands_only`).
//!
//! `cargo bench --bench compensate [-- TARGETS] [full | commands-only] [--length MM]` (default 100,000
//! targets over the whole 200 mm line, both modes); `scripts/bench-compensate` runs it with the `dist` profile and adds the command line's thread
//! scaling.

use std::path::Path;
use std::time::Instant;

use stiff::kinematics::frame::{Vec3, Vec6};
use stiff::model::assembly_errors::ErrorSet;
use stiff::model::grid::path_points;
use stiff::study::assemble::LegErrors;
use stiff::study::compensate::{CompensateOptions, Compensator, Method, RealRobot};
use stiff::study::point::Status;

fn main() {
    // Arguments: TARGETS, `full` or `commands-only` (that mode alone, e.g. under callgrind), `--length MM`
    // (the first MM of the line: the same spacing for fewer targets, for instruction counts).
    let (mut targets, mut length, mut modes_asked) = (100_000usize, 200.0f64, Vec::new());
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--length" => length = args.next().and_then(|v| v.parse().ok()).expect("--length takes a length in mm"),
            "full" | "commands-only" => modes_asked.push(a),
            _ => targets = a.parse().unwrap_or(targets),
        }
    }
    let model = Path::new("manipulators/orthoglide-3puu.toml");
    let m = stiff::model::load_manipulator(model).expect("the shipped model");
    let set = ErrorSet::load(Path::new("manipulators/errors/orthoglide-case-b.toml"), model, &m).expect("Case B");
    let perturbed = set.perturbed_legs(1.0).expect("no parameter errors");
    let robot = RealRobot { nominal: &m, errors: Some((LegErrors { set: &set, perturbed: &perturbed }, 1.0)) };
    let path = path_points(&Vec3::new(-73.65, -73.65, -73.65), &Vec3::new(-73.65, -73.65 + length, -73.65), targets);
    let modes = [(false, "full rows", "full"), (true, "commands only (--commands-only)", "commands-only")];
    let chosen = modes.iter().filter(|(_, _, name)| modes_asked.is_empty() || modes_asked.iter().any(|m| m == name));
    for &(commands_only, what, _) in chosen {
        let wrench = Vec6::new(215.0, -10.0, -25.0, 1000.0, 21500.0, 0.0);
        let options = CompensateOptions { wrench: Some(wrench), method: Method::Newton, scale: 1.0, commands_only };
        let compensator = Compensator::new(&robot, &options);
        let mut state = compensator.start();
        let mut latencies = Vec::with_capacity(targets);
        let (mut steps, mut equilibria, mut worst_residual) = (0usize, 0usize, 0.0f64);
        let start = Instant::now();
        for p in &path {
            let t = Instant::now();
            let (_, c) = compensator.next(p, &mut state);
            latencies.push(t.elapsed().as_secs_f64() * 1e6);
            assert_eq!(c.status, Status::Ok, "target {:?}", p.position);
            steps += c.iterations.unwrap_or(0);
            equilibria += c.equilibria;
            worst_residual = worst_residual.max(c.residual.map_or(f64::NAN, |r| r.fixed_rows::<3>(0).norm()));
        }
        let total = start.elapsed().as_secs_f64();
        let in_order = latencies.clone();
        latencies.sort_by(f64::total_cmp);
        let at = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
        let n = targets as f64;
        let spacing = length / (targets.max(2) - 1) as f64;
        println!(
            "{targets} targets {spacing:.4} mm apart on the milling line (Case B, cutting wrench), one core, {what}:"
        );
        println!("  {:.0} targets/s, {:.1} us per target", n / total, 1e6 * total / n);
        println!("  latency: median {:.1} us, 99th percentile {:.1} us, largest {:.1} us", at(0.5), at(0.99), at(1.0));
        if let Some(rate) = fastest_stretch(&in_order, STRETCH) {
            println!("  fastest {STRETCH} consecutive targets: {rate:.0} targets/s (the machine least disturbed)");
        }
        println!(
            "  {:.2} commands after the mirror and {:.2} loaded equilibria per target",
            steps as f64 / n,
            equilibria as f64 / n
        );
        println!("  largest residual {worst_residual:.2e} mm");
    }
}

/// Targets in the stretch whose speed `fastest_stretch` reports: long enough to span many scheduler ticks
/// (about 0.3 s), short enough that a shared machine leaves some such stretch undisturbed.
const STRETCH: usize = 10_000;

/// Targets per second over the fastest `n` consecutive targets (their latencies in microseconds, in path
/// order), None where there are fewer. On a machine shared with other work the whole run's rate measures
/// the neighbours too; the fastest stretch is the code's own speed.
fn fastest_stretch(latencies_us: &[f64], n: usize) -> Option<f64> {
    if latencies_us.len() < n {
        return None;
    }
    let mut window: f64 = latencies_us[..n].iter().sum();
    let mut best = window;
    for (added, dropped) in latencies_us[n..].iter().zip(latencies_us) {
        window += added - dropped;
        best = best.min(window);
    }
    Some(n as f64 / (best * 1e-6))
}
