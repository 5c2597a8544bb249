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

/// A 5 x 5 x 5 grid: five sections of 25 cells, a colour bar, units on the axes and the bar.
#[test]
fn map_plot_has_a_cell_per_point_and_units() {
    let csv = map_csv();
    let svg = plot_text(&csv, &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "rect", "cell"), 125);
    assert_eq!(count(&doc, "rect", "colorbar"), 50);
    let t = texts(&doc);
    assert!(t.iter().any(|s| s == "x [mm]") && t.iter().any(|s| s == "[mm/N]"), "{t:?}");
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
    assert_eq!(count(&doc, "rect", "bic-bar"), identifiable);
    assert!(texts(&doc).iter().any(|s| s == "verdict: effect (tool-offset)"));
}

/// A two-thread pool for the streamed studies (their output does not depend on the thread count).
fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap()
}
