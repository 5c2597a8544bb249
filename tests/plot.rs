//! Pictures: every kind parses as XML, has the marks and labels its data calls for, axis labels carry units,
//! and one small case matches a golden file (looked at, as PNG, when it was made: see the closing note).

use std::path::Path;

use stiff::plot::{plot_text, PlotOptions};

fn parse(svg: &str) -> roxmltree::Document<'_> {
    roxmltree::Document::parse(svg).expect("the SVG is well-formed XML")
}

fn count(doc: &roxmltree::Document, tag: &str, class: &str) -> usize {
    doc.descendants().filter(|n| n.has_tag_name(tag) && n.attribute("class") == Some(class)).count()
}

fn texts(doc: &roxmltree::Document) -> Vec<String> {
    doc.descendants().filter(|n| n.has_tag_name("text")).filter_map(|n| n.text().map(String::from)).collect()
}

/// A numeric column of a CSV, read with the csv crate (empty cells left out).
fn column(csv: &str, name: &str) -> Vec<f64> {
    let mut r = csv::Reader::from_reader(csv.as_bytes());
    let k = r.headers().unwrap().iter().position(|h| h == name).unwrap();
    r.records().filter_map(|row| row.unwrap()[k].parse().ok()).collect()
}

fn map_csv() -> String {
    let m = stiff::model::load_manipulator(Path::new("manipulators/orthoglide-3puu.toml")).unwrap();
    let mut points =
        stiff::model::grid::PointSet::from_grid_file(Path::new("manipulators/grids/orthoglide-small.toml")).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut out: Vec<u8> = Vec::new();
    let bar = indicatif::ProgressBar::hidden();
    stiff::study::map::run_map(&pool, &m, &mut points, Default::default(), &mut out, &bar).unwrap();
    String::from_utf8(out).unwrap()
}

/// A 5 x 5 x 5 grid: five sections of 25 cells, a colour bar whose labels include both ends of the data
/// (the column's smallest and largest value, read from the CSV here), the extremes marked, units on the
/// axes and the bar.
#[test]
fn map_plot_has_a_cell_per_point_and_units() {
    let csv = map_csv();
    let svg = plot_text(&csv, &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "rect", "cell"), 125);
    assert!(count(&doc, "rect", "colorbar") > 20);
    let t = texts(&doc);
    assert!(t.iter().any(|s| s == "x [mm]") && t.iter().any(|s| s == "[mm/N]"), "{t:?}");
    let values = column(&csv, "c_tran_max_mm_per_N");
    let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    let label = stiff::plot::svg::tick_label;
    assert!(t.contains(&label(lo)) && t.contains(&label(hi)), "colour bar ends {} {} in {t:?}", label(lo), label(hi));
    assert!(t.contains(&format!("min {}", label(lo))) && t.contains(&format!("max {}", label(hi))));
    assert_eq!(t.iter().filter(|s| s.starts_with("z = ")).count(), 5);
    let one = plot_text(
        &csv,
        &PlotOptions { section: Some("z=0".into()), column: Some("C44_rad_per_Nmm".into()), ..Default::default() },
    )
    .unwrap();
    let doc = parse(&one);
    assert_eq!(count(&doc, "rect", "cell"), 25);
    assert!(texts(&doc).iter().any(|s| s == "[rad/N mm]"));
    assert!(plot_text(&csv, &PlotOptions { section: Some("z=17".into()), ..Default::default() }).is_err());
}

/// A hand-made curve (tests/golden/curve-small.csv: stable, then unstable after a buckling event, then restabilised): two solid and one
/// dashed branch, two event marks; matches the golden file.
#[test]
fn curve_plot_marks_events_and_dashes_the_unstable_branch() {
    let csv = std::fs::read_to_string("tests/golden/curve-small.csv").unwrap();
    assert!(csv.starts_with(&stiff::study::curve::curve_header()), "the curve CSV format");
    let svg = plot_text(&csv, &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "polyline", "stable"), 2);
    assert_eq!(count(&doc, "polyline", "unstable"), 1);
    assert_eq!(count(&doc, "circle", "event"), 2);
    let t = texts(&doc);
    assert!(t.iter().any(|s| s == "dx [mm]") && t.iter().any(|s| s == "Fx [N]") && t.iter().any(|s| s == "buckling"));
    let golden = std::fs::read_to_string("tests/golden/curve-small.svg").unwrap();
    assert_eq!(svg, golden, "regenerate with scripts/regenerate-golden after looking at the picture");
}

/// Regression: the dashed unstable branch started at the first unstable row, before the buckling mark,
/// which sits where the curve study bisected the loss of positive definiteness (load factor 19 between rows
/// at 18 and 20). Stability changes where its event lies: the dashed branch starts at the buckling mark
/// and ends at the restabilisation mark, and the solid branches meet them there.
#[test]
fn the_unstable_branch_runs_from_its_buckling_mark_to_its_restabilisation_mark() {
    let csv = std::fs::read_to_string("tests/golden/curve-small.csv").unwrap();
    let doc_text = plot_text(&csv, &PlotOptions::default()).unwrap();
    let doc = parse(&doc_text);
    let points = |class: &str| -> Vec<Vec<(f64, f64)>> {
        doc.descendants()
            .filter(|n| n.has_tag_name("polyline") && n.attribute("class") == Some(class))
            .map(|n| {
                n.attribute("points")
                    .unwrap()
                    .split(' ')
                    .map(|p| {
                        let (x, y) = p.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect()
            })
            .collect()
    };
    let marks: Vec<(f64, f64)> = doc
        .descendants()
        .filter(|n| n.has_tag_name("circle") && n.attribute("class") == Some("event"))
        .map(|n| (n.attribute("cx").unwrap().parse().unwrap(), n.attribute("cy").unwrap().parse().unwrap()))
        .collect();
    let unstable = &points("unstable")[0];
    let stable = points("stable");
    let near = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 0.02 && (a.1 - b.1).abs() < 0.02;
    assert!(near(unstable[0], marks[0]), "dashed starts at buckling: {:?} vs {:?}", unstable[0], marks[0]);
    assert!(near(*unstable.last().unwrap(), marks[1]), "dashed ends at restabilisation");
    assert!(near(*stable[0].last().unwrap(), marks[0]) && near(stable[1][0], marks[1]), "solid meets the marks");
    // The buckling mark lies halfway between the rows at load factors 18 and 20 (dx 0.25 and 0.5 mm).
    let rows = column(&csv, "dx_mm");
    let x = |dx: f64| stable[0][0].0 + (dx - rows[0]) / (rows[1] - rows[0]) * (stable[0][1].0 - stable[0][0].0);
    assert!((marks[0].0 - x(0.375)).abs() < 0.02, "{} vs {}", marks[0].0, x(0.375));
}

/// The milling path of paper 000 (Case A, 11 points) with the cutting wrench: three panels (x, y, z) with four
/// series each and the target line.
#[test]
fn assemble_plot_draws_figure_10() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.csv");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
        .args([
            "assemble",
            "manipulators/orthoglide-3puu.toml",
            "--errors",
            "manipulators/errors/orthoglide-case-a.toml",
        ])
        .args([
            "--path",
            "-73.65,-73.65,-73.65",
            "-73.65,126.35,-73.65",
            "11",
            "--wrench",
            "215,-10,-25,1000,21500,0",
            "-q",
            "-o",
        ])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let svg = plot_text(&std::fs::read_to_string(&out).unwrap(), &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "polyline", "series"), 12);
    assert_eq!(count(&doc, "line", "target"), 3);
    let t = texts(&doc);
    for label in ["dx [mm]", "dz [mm]", "y [mm] along the path", "superposition", "cutting load"] {
        assert!(t.iter().any(|s| s == label), "{label} in {t:?}");
    }
}

/// A diagnosis: one pair of arrows per pose, per-axis RMS bars, a delta-BIC bar per identifiable candidate.
#[test]
fn diagnose_plot_has_arrows_and_bars() {
    let m = stiff::model::load_manipulator(Path::new("manipulators/orthoglide-3puu.toml")).unwrap();
    let points: Vec<_> =
        [(-60.0, -60.0, 0.0), (60.0, -60.0, 0.0), (-60.0, 60.0, 0.0), (60.0, 60.0, 40.0), (0.0, 0.0, -40.0)]
            .iter()
            .map(|&(x, y, z)| stiff::model::grid::PosePoint {
                name: None,
                position: [x, y, z].into(),
                rotation: Default::default(),
                wrench: None,
            })
            .collect();
    let mut wrenches = vec![stiff::kinematics::frame::Vec6::zeros()];
    for k in 0..3 {
        for s in [200.0, -200.0] {
            let mut w = stiff::kinematics::frame::Vec6::zeros();
            w[k] = s;
            wrenches.push(w);
        }
    }
    let effect = stiff::model::effect::Effect::parse("tool-offset=0.05,0,0", &m).unwrap();
    let o = stiff::diagnose::synth::SynthOptions { effects: vec![effect], wrenches, noise: 0.002, seed: 1, repeats: 1 };
    let mut text = Vec::new();
    let mut points = stiff::model::grid::PointSet::from_points(points);
    stiff::diagnose::synth::synthesize(
        &pool(),
        &stiff::model::Model::nominal(m.clone()),
        &mut points,
        &o,
        &mut text,
        &indicatif::ProgressBar::hidden(),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.csv");
    std::fs::write(&path, text).unwrap();
    let data = stiff::diagnose::data::Dataset::read(&path).unwrap();
    let (weights, sigma, source) = stiff::diagnose::select::noise(&data, None).unwrap();
    let problem = stiff::diagnose::fit::Problem::new(&m, &[], &data, weights, false, true).unwrap();
    let d = stiff::diagnose::select::diagnose(&problem, sigma, source, &Default::default()).unwrap();
    let json = stiff::diagnose::report::json(&d, "model");
    let svg = plot_text(&serde_json::to_string(&json).unwrap(), &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "line", "before"), 5);
    assert_eq!(count(&doc, "line", "after"), 5);
    assert_eq!(count(&doc, "rect", "rms-bar"), 12);
    let identifiable = d.table.iter().filter(|r| r.identifiable).count();
    assert_eq!(count(&doc, "rect", "bic-bar") + count(&doc, "rect", "bic-bar accepted"), identifiable);
    assert_eq!(count(&doc, "rect", "bic-bar accepted"), 1, "the accepted effect is set apart");
    let t = texts(&doc);
    assert!(t.iter().any(|s| s == "diagnosis of model: verdict effect (tool-offset)"), "{t:?}");
    assert!(t.iter().any(|s| s == "tool-offset (accepted)"));
    // Every arrow ends inside a panel's frame (four frame lines per panel).
    let frames: Vec<[f64; 4]> = lines(&doc, "frame")
        .chunks(4)
        .map(|c| {
            let xs = c.iter().flat_map(|l| [l.0, l.2]);
            let ys = c.iter().flat_map(|l| [l.1, l.3]);
            [
                xs.clone().fold(f64::MAX, f64::min),
                ys.clone().fold(f64::MAX, f64::min),
                xs.fold(f64::MIN, f64::max),
                ys.fold(f64::MIN, f64::max),
            ]
        })
        .collect();
    for arrow in lines(&doc, "before").iter().chain(&lines(&doc, "after")) {
        let inside = |x: f64, y: f64, f: &[f64; 4]| x >= f[0] && x <= f[2] && y >= f[1] && y <= f[3];
        assert!(frames.iter().any(|f| inside(arrow.0, arrow.1, f) && inside(arrow.2, arrow.3, f)), "{arrow:?}");
    }
    // Each key is a round length: 1, 2 or 5 times a power of ten.
    let keys: Vec<f64> = t.iter().filter_map(|s| s.strip_suffix(" mm residual")).map(|v| v.parse().unwrap()).collect();
    assert_eq!(keys.len(), 2);
    for k in keys {
        let mantissa = k / 10f64.powf(k.log10().floor());
        assert!([1.0, 2.0, 5.0].iter().any(|m| (mantissa - m).abs() < 1e-9), "key {k}");
    }
}

/// The (x1, y1, x2, y2) of every line of a class.
fn lines(doc: &roxmltree::Document, class: &str) -> Vec<(f64, f64, f64, f64)> {
    let at = |n: &roxmltree::Node, a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
    doc.descendants()
        .filter(|n| n.has_tag_name("line") && n.attribute("class") == Some(class))
        .map(|n| (at(&n, "x1"), at(&n, "y1"), at(&n, "x2"), at(&n, "y2")))
        .collect()
}

/// A two-thread pool for the streamed studies (their output does not depend on the thread count).
fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap()
}
