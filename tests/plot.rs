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
    assert!(t.iter().any(|s| s == "x [mm]"), "{t:?}");
    let values = column(&csv, "c_tran_max_mm_per_N");
    let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    // The bar's unit names the power of ten its labels are multiples of (`[10⁻³ mm/N]`), as matplotlib does.
    let unit = t.iter().find(|s| s.ends_with("mm/N]")).unwrap();
    let power = unit.strip_prefix("[10").map_or("⁰", |p| p.trim_end_matches(" mm/N]"));
    let digits: String = power
        .chars()
        .map(|c| match c {
            '⁻' => '-',
            c => char::from_digit("⁰¹²³⁴⁵⁶⁷⁸⁹".chars().position(|d| d == c).unwrap() as u32, 10).unwrap(),
        })
        .collect();
    let scale = 10f64.powi(digits.parse().unwrap());
    let shown = |v: f64| t.iter().any(|s| s.parse::<f64>().is_ok_and(|x| (x * scale - v).abs() <= 5e-4 * v.abs()));
    assert!(shown(lo) && shown(hi), "colour bar ends {lo} {hi} in {t:?} (x {scale})");
    let label = stiff::plot::svg::tick_label;
    assert!(t.contains(&format!("min {}", label(lo))) && t.contains(&format!("max {}", label(hi))));
    assert_eq!(t.iter().filter(|s| s.starts_with("z = ")).count(), 5);
    let one = plot_text(
        &csv,
        &PlotOptions { section: Some("z=0".into()), column: Some("C44_rad_per_Nmm".into()), ..Default::default() },
    )
    .unwrap();
    let doc = parse(&one);
    assert_eq!(count(&doc, "rect", "cell"), 25);
    assert!(texts(&doc).iter().any(|s| s.ends_with(" rad/N mm]")), "{:?}", texts(&doc));
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

/// A compensated milling path (paper 000 Figures 10-11 with the compensation): per axis the error without
/// compensation, with the mirror command and with Newton's command (three lines on three panels), each named
/// in the legend with its largest length as the table gives it; with the mirror method, two lines.
#[test]
fn compensate_plot_draws_the_errors_before_and_after() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.csv");
    let run = |method: &str| {
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_stiff"))
            .args([
                "compensate",
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
            ])
            .args(["--method", method, "-q", "-o"])
            .arg(&out)
            .status()
            .unwrap();
        assert!(status.success());
        let csv = std::fs::read_to_string(&out).unwrap();
        (plot_text(&csv, &PlotOptions::default()).unwrap(), csv)
    };
    let (svg, csv) = run("newton");
    let doc = parse(&svg);
    assert_eq!(count(&doc, "polyline", "series"), 9);
    assert_eq!(count(&doc, "line", "target"), 3);
    let largest = column(&csv, "uncompensated_error_mm").into_iter().fold(0.0, f64::max);
    let t = texts(&doc);
    let legend = format!("without compensation (largest {} mm)", stiff::plot::svg::tick_label(largest));
    for label in ["dx [mm]", "dz [mm]", "y [mm] along the path", legend.as_str()] {
        assert!(t.iter().any(|s| s == label), "{label} in {t:?}");
    }
    assert!(t.iter().any(|s| s.starts_with("mirror command (largest")), "{t:?}");
    assert!(t.iter().any(|s| s.starts_with("Newton's command, forward solve (largest")), "{t:?}");
    let (svg, _) = run("mirror");
    assert_eq!(count(&parse(&svg), "polyline", "series"), 6);
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
                joints: Vec::new(),
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
    let o = stiff::diagnose::synth::SynthOptions {
        effects: vec![effect],
        wrenches,
        noise: 0.002,
        seed: 1,
        repeats: 1,
        linear: false,
        portion: false,
    };
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
    let problem = stiff::diagnose::fit::Problem::new(&m, &[], &data, weights, true, true).unwrap();
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

/// Asserts a run failed (exit 1) saying `why`.
fn assert_refused(o: &std::process::Output, why: &str) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains(why), "`{why}` not in: {stderr}");
}

/// Runs stiff with these arguments in `dir` (shipped files by their path from the repository root).
fn stiff_in(dir: &Path, args: &[&str]) -> std::process::Output {
    let root = std::env::current_dir().unwrap();
    let args: Vec<String> =
        args.iter()
            .map(|a| {
                if a.starts_with("manipulators/") {
                    root.join(a).to_string_lossy().into_owned()
                } else {
                    a.to_string()
                }
            })
            .collect();
    std::process::Command::new(env!("CARGO_BIN_EXE_stiff")).args(&args).current_dir(dir).output().unwrap()
}

/// The text boxes of a picture (from the same Helvetica-based metrics the layout uses), with rotation.
fn text_boxes(doc: &roxmltree::Document) -> Vec<(String, [f64; 4])> {
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| {
            let at = |a: &str| n.attribute(a).unwrap().parse::<f64>().unwrap();
            let (x, y, size) = (at("x"), at("y"), at("font-size"));
            let t = n.text().unwrap_or("").to_string();
            let w = stiff::plot::svg::text_width(&t, size);
            let x0 = match n.attribute("text-anchor") {
                Some("middle") => x - w / 2.0,
                Some("end") => x - w,
                _ => x,
            };
            let b = if n.attribute("transform").is_some_and(|r| r.starts_with("rotate(-90")) {
                // Turned a quarter left about its anchor: the width runs up the page.
                [x - 0.75 * size, y + (x - x0) - w, x + 0.2 * size, y + (x - x0)]
            } else {
                [x0, y - 0.75 * size, x0 + w, y + 0.2 * size]
            };
            (t, b)
        })
        .collect()
}

/// No two texts of a picture overlap.
fn assert_no_text_overlaps(svg: &str, what: &str) {
    let doc = parse(svg);
    let boxes = text_boxes(&doc);
    for (i, (a, p)) in boxes.iter().enumerate() {
        for (b, q) in &boxes[i + 1..] {
            // Texts closer than 1 px count as overlapping: they touch on screen.
            let overlap = p[0] < q[2] + 1.0 && q[0] < p[2] + 1.0 && p[1] < q[3] + 1.0 && q[1] < p[3] + 1.0;
            assert!(!overlap, "{what}: `{a}` {p:?} overlaps `{b}` {q:?}");
        }
    }
}

/// The overlap check finds overlaps: two labels on one spot, and a y-axis label on its tick labels.
#[test]
#[should_panic(expected = "overlaps")]
fn the_overlap_check_sees_overlapping_text() {
    assert_no_text_overlaps(
        r#"<svg xmlns="http://www.w3.org/2000/svg"><text x="50" y="50" font-size="11" text-anchor="end">-0.005</text><text x="30" y="48" font-size="12" text-anchor="middle" transform="rotate(-90 30 48)">dx [mm]</text></svg>"#,
        "test",
    );
}

/// Each table gets the picture its poses call for: a grid the colour map of the chosen column
/// (`--plot-column` honoured), named points a labelled dot chart, a line of points a line chart against
/// its coordinate, scattered points coloured markers, a tolerance study the map of its mean displacement;
/// a single unnamed point is refused. Every title says what it shows, and no two texts overlap.
#[test]
fn each_table_gets_the_picture_its_poses_call_for() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let errors = "manipulators/errors/orthoglide-case-a.toml";
    let model = "manipulators/orthoglide-3puu.toml";
    // The largest value at the top right corner: its label once ran into the colour bar's unit.
    std::fs::write(
        d.join("scatter.csv"),
        "x_mm,y_mm,z_mm\n0,0,0\n30,-20,10\n-40,25,-5\n12,44,30\n-25,-35,20\n60,60,60\n",
    )
    .unwrap();
    std::fs::write(d.join("line.csv"), "x_mm,y_mm,z_mm\n-50,0,0\n0,0,0\n50,0,0\n25,0,0\n-25,0,0\n").unwrap();
    std::fs::write(d.join("one.csv"), "x_mm,y_mm,z_mm\n0,0,0\n").unwrap();
    let picture = |args: &[&str]| -> String {
        let o = stiff_in(d, args);
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        let svg = std::fs::read_to_string(d.join(args[args.iter().position(|a| *a == "--plot").unwrap() + 1])).unwrap();
        assert_no_text_overlaps(&svg, &args.join(" "));
        svg
    };
    let grid = picture(&[
        "assemble",
        model,
        "--errors",
        errors,
        "--grid",
        "manipulators/grids/orthoglide-small.toml",
        "-q",
        "-o",
        "g.csv",
        "--plot",
        "g.svg",
        "--plot-column",
        "nl_dz_mm",
    ]);
    let doc = parse(&grid);
    assert_eq!(count(&doc, "rect", "cell"), 125);
    assert!(texts(&doc).iter().any(|t| t == "nl_dz [mm] over sections z = const"), "{:?}", texts(&doc));
    assert!(texts(&doc)[0].starts_with("Orthoglide 3-PUU (") && texts(&doc).iter().any(|t| t.contains("errors")));

    let named = picture(&[
        "assemble",
        model,
        "--errors",
        errors,
        "--grid",
        "manipulators/grids/orthoglide-q.toml",
        "-q",
        "-o",
        "q.csv",
        "--plot",
        "q.svg",
    ]);
    let doc = parse(&named);
    assert_eq!(count(&doc, "circle", "point"), 3);
    assert_eq!(count(&doc, "polyline", "series"), 0, "named points are not a path");
    for q in ["Q0", "Q1", "Q2"] {
        assert!(texts(&doc).iter().any(|t| t == q));
    }

    let samples = picture(&[
        "assemble",
        model,
        "--errors",
        errors,
        "--grid",
        "manipulators/grids/orthoglide-small.toml",
        "--samples",
        "5",
        "-q",
        "-o",
        "s.csv",
        "--plot",
        "s.svg",
    ]);
    assert!(texts(&parse(&samples)).iter().any(|t| t == "displacement_mean [mm] over sections z = const"));

    let scatter = picture(&["map", model, "--points", "scatter.csv", "-q", "-o", "sc.csv", "--plot", "sc.svg"]);
    let doc = parse(&scatter);
    assert_eq!(count(&doc, "circle", "point"), 6);
    assert_eq!(count(&doc, "rect", "cell"), 0, "scattered points are not cells");

    let line = picture(&["map", model, "--points", "line.csv", "-q", "-o", "l.csv", "--plot", "l.svg"]);
    let doc = parse(&line);
    assert_eq!(count(&doc, "polyline", "series"), 1);
    assert!(texts(&doc).iter().any(|t| t == "x [mm]"));
    let xs: Vec<f64> = doc
        .descendants()
        .filter(|n| n.has_tag_name("circle") && n.attribute("class") == Some("point"))
        .map(|n| n.attribute("cx").unwrap().parse().unwrap())
        .collect();
    assert_eq!(xs.len(), 5);

    let o = stiff_in(d, &["map", model, "--points", "one.csv", "-q", "-o", "one.csv.out.csv", "--plot", "one.svg"]);
    assert_refused(&o, "a single point has no map picture");
    assert!(!d.join("one.svg").exists());
}

/// Shipped example pictures have no overlapping text: the map of the cube, a curve with buckling, the
/// milling path, a diagnosis.
#[test]
fn shipped_pictures_have_no_overlapping_text() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = "manipulators/orthoglide-3puu.toml";
    for args in [
        vec!["map", model, "--grid", "manipulators/grids/orthoglide-cube.toml", "-q", "-o", "m.csv", "--plot", "m.svg"],
        vec![
            "curve",
            model,
            "--at",
            "0,0,0",
            "--wrench-direction",
            "1,0,0,0,0,0",
            "--max",
            "20000",
            "-q",
            "-o",
            "c.csv",
            "--plot",
            "c.svg",
        ],
        vec![
            "assemble",
            model,
            "--errors",
            "manipulators/errors/orthoglide-case-b.toml",
            "--path",
            "-200,0,0",
            "300,0,0",
            "26",
            "--wrench",
            "215,-10,-25,1000,21500,0",
            "-q",
            "-o",
            "p.csv",
            "--plot",
            "p.svg",
        ],
        vec![
            "compensate",
            model,
            "--errors",
            "manipulators/errors/orthoglide-case-a.toml",
            "--path",
            "-73.65,-73.65,-73.65",
            "-73.65,126.35,-73.65",
            "21",
            "--wrench",
            "215,-10,-25,1000,21500,0",
            "-q",
            "-o",
            "k.csv",
            "--plot",
            "k.svg",
        ],
    ] {
        let o = stiff_in(d, &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let svg = std::fs::read_to_string(d.join(args.last().unwrap())).unwrap();
        assert_no_text_overlaps(&svg, &args.join(" "));
    }
}

/// Colours: a log scale labels decades and both ends; a fixed range maps values outside it to the end
/// colours and is named on the bar; a log scale over values that are not positive is refused.
#[test]
fn colour_scales_are_log_or_linear_over_the_data_or_a_range() {
    let csv = map_csv();
    let log = plot_text(&csv, &PlotOptions { scale: stiff::plot::Scale::Log, ..Default::default() }).unwrap();
    let t = texts(&parse(&log));
    assert!(t.iter().any(|s| s == "[mm/N, log]"), "{t:?}");
    let ranged = plot_text(&csv, &PlotOptions { range: Some((0.0, 0.1)), ..Default::default() }).unwrap();
    let t = texts(&parse(&ranged));
    assert!(t.iter().any(|s| s == "0") && t.iter().any(|s| s == "0.1"), "{t:?}");
    let bad = PlotOptions { scale: stiff::plot::Scale::Log, column: Some("dx_mm".into()), ..Default::default() };
    let csv_with_wrench = std::fs::read_to_string("tests/golden/orthoglide-3puu-small.csv").unwrap();
    if column(&csv_with_wrench, "C12_mm_per_N").iter().any(|v| *v <= 0.0) {
        let e = plot_text(&csv_with_wrench, &PlotOptions { column: Some("C12_mm_per_N".into()), ..bad }).unwrap_err();
        assert!(e.to_string().contains("log colour scale needs positive values"), "{e}");
    }
}

/// Above `RASTER_CELLS` cells a section is one embedded PNG, not a rectangle per cell: a 101 x 101 section
/// (10,201 cells) gives one image and no cell rectangles, and a far smaller file.
#[test]
fn large_sections_are_drawn_as_one_image() {
    let mut csv = String::from("x_mm,y_mm,z_mm,status,c_tran_max_mm_per_N\n");
    for j in 0..101 {
        for i in 0..101 {
            csv.push_str(&format!(
                "{},{},0,ok,{}\n",
                i as f64 - 50.0,
                j as f64 - 50.0,
                1e-3 * (1.0 + (i * j) as f64 / 1e4)
            ));
        }
    }
    const { assert!(101 * 101 > stiff::plot::points::RASTER_CELLS) };
    let svg = plot_text(&csv, &PlotOptions::default()).unwrap();
    let doc = parse(&svg);
    assert_eq!(count(&doc, "image", "cells"), 1);
    assert_eq!(count(&doc, "rect", "cell"), 0);
    let href = doc.descendants().find(|n| n.has_tag_name("image")).unwrap().attribute("href").unwrap();
    assert!(href.starts_with("data:image/png;base64,iVBORw0KGgo"), "a PNG (its signature in base64)");
    assert!(svg.len() < 100_000, "{} bytes", svg.len());
}

/// `--plot FILE.png` writes a PNG rendered without system fonts (DejaVu Sans is embedded): twice the SVG's
/// size, and its title drawn (dark pixels where the heading is, white around).
#[test]
fn pictures_render_to_png_with_their_text() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = stiff_in(
        d,
        &[
            "map",
            "manipulators/orthoglide-3puu.toml",
            "--grid",
            "manipulators/grids/orthoglide-small.toml",
            "-q",
            "-o",
            "m.csv",
            "--plot",
            "m.svg",
        ],
    );
    assert!(o.status.success());
    let o = stiff_in(d, &["plot", "m.csv", "-o", "m.png", "--title", "Orthoglide"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = std::fs::read(d.join("m.png")).unwrap();
    let pixmap = resvg::tiny_skia::Pixmap::decode_png(&png).expect("a PNG");
    let svg = std::fs::read_to_string(d.join("m.svg")).unwrap();
    let doc = parse(&svg);
    let root = doc.root_element();
    let (w, h): (f64, f64) =
        (root.attribute("width").unwrap().parse().unwrap(), root.attribute("height").unwrap().parse().unwrap());
    assert_eq!((pixmap.width(), pixmap.height()), ((2.0 * w) as u32, (2.0 * h) as u32));
    // The title "Orthoglide" is centred on the first line (baseline at y = 22 in SVG units).
    let dark = |x0: u32, x1: u32, y0: u32, y1: u32| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| pixmap.pixel(x, y).unwrap().red() < 100)
            .count()
    };
    let centre = pixmap.width() / 2;
    assert!(dark(centre - 60, centre + 60, 20, 48) > 100, "the title is drawn");
    assert_eq!(dark(0, 40, 0, 40), 0, "the corner is blank");
}

/// Tables a picture cannot be drawn from are refused with a message, never a panic: no rows, rows at one
/// pose, positions missing; odd values (text in a number column, every value missing, huge coordinates)
/// still give a well-formed picture.
#[test]
fn odd_tables_are_refused_or_drawn_never_a_panic() {
    let header = "x_mm,y_mm,z_mm,status,c_tran_max_mm_per_N\n";
    for (rows, refused) in [
        ("", Some("no rows")),
        ("1,2,3,ok,0.1\n1,2,3,ok,0.2\n", Some("same pose")),
        ("1,,3,ok,0.1\n2,2,3,ok,0.2\n", Some("needs a position")),
        ("0,0,0,ok,abc\n1,0,0,ok,0.2\n2,0,0,ok,\n", None),
        ("0,0,0,bad,\n1,0,0,bad,\n0,1,0,bad,\n1,1,0,bad,\n", None),
        ("0,0,0,ok,1\n1e300,0,0,ok,2\n0,1e300,5,ok,3\n", None),
    ] {
        let csv = format!("{header}{rows}");
        match (plot_text(&csv, &PlotOptions::default()), refused) {
            (Ok(svg), None) => {
                parse(&svg);
            }
            (Err(e), Some(why)) => assert!(e.to_string().contains(why), "{rows:?}: {e}"),
            (r, _) => panic!("{rows:?}: {:?}", r.map(|s| s.len())),
        }
    }
    for text in ["", "   \n", "a,b\n1,2\n", "{\"not\": \"a diagnosis\"}"] {
        assert!(plot_text(text, &PlotOptions::default()).is_err(), "{text:?}");
    }
}

/// A map picture places each point by its position: `--plot` with `--columns` that drop the poses is
/// refused before the map is computed, and nothing is written.
#[test]
fn a_map_picture_needs_the_positions_written() {
    let dir = tempfile::tempdir().unwrap();
    let o = stiff_in(
        dir.path(),
        &[
            "map",
            "manipulators/orthoglide-3puu.toml",
            "--grid",
            "manipulators/grids/orthoglide-small.toml",
            "--columns",
            "status,principal",
            "-o",
            "m.csv",
            "--plot",
            "m.svg",
        ],
    );
    assert_refused(&o, "keep the group pose");
    assert!(!dir.path().join("m.csv").exists() && !dir.path().join("m.svg").exists());
}

/// A picture that cannot be written is refused before the work: an unwritable `--plot` path stops a map
/// before it is computed (no table written either), and `stiff plot` says so before drawing.
#[test]
fn an_unwritable_picture_is_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let o = stiff_in(
        dir.path(),
        &[
            "map",
            "manipulators/orthoglide-3puu.toml",
            "--grid",
            "manipulators/grids/orthoglide-small.toml",
            "-q",
            "-o",
            "m.csv",
            "--plot",
            "missing/m.svg",
        ],
    );
    assert_refused(&o, "the folder missing does not exist");
    assert!(!dir.path().join("m.csv").exists(), "the map was not computed");
    assert_refused(
        &stiff_in(dir.path(), &["plot", "nothing.csv", "-o", "missing/p.png"]),
        "the folder missing does not exist",
    );
}

/// A serial arm's calibration (`diagnose --plot` on joint-space data, and `stiff plot` of its JSON): one RMS
/// bar per stage for the fitted rows and one for the held-out rows, each as tall as the JSON's RMS (heights
/// in proportion to 1e-3, the SVG's hundredth of a pixel), the stages named, the axis in mm, no text on
/// another; with orientations measured, a second panel of their errors in mrad, its bars in proportion to
/// the JSON's orientation RMS alike.
#[test]
fn a_calibration_plot_has_a_bar_per_stage_and_row_set() {
    let dir = tempfile::tempdir().unwrap();
    let synth = stiff_in(
        dir.path(),
        &["synth", "manipulators/fanuc-r2000ic.toml", "--points", "manipulators/grids/fanuc-r2000ic-cable-tests.csv"]
            .into_iter()
            .chain(["--effect", "registration=0.1,0,0.2,1500,0,300", "--effect", "joint-offset:J2=0.002"])
            .chain(["--noise", "0.05", "--orientation-noise", "0.1", "--seed", "1", "--check-every", "3"])
            .chain(["-o", "cal.csv"])
            .collect::<Vec<_>>(),
    );
    assert!(synth.status.success(), "{}", String::from_utf8_lossy(&synth.stderr));
    let diagnose = stiff_in(
        dir.path(),
        &[
            "diagnose",
            "manipulators/fanuc-r2000ic.toml",
            "--data",
            "cal.csv",
            "--plot",
            "cal.svg",
            "--json",
            "cal.json",
        ],
    );
    assert!(diagnose.status.success(), "{}", String::from_utf8_lossy(&diagnose.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("cal.json")).unwrap()).unwrap();
    let stages = json["calibration"]["stages"].as_array().unwrap();
    assert!(stages.len() >= 2, "{json}");
    let replotted = stiff_in(dir.path(), &["plot", "cal.json", "-o", "again.svg"]);
    assert!(replotted.status.success(), "{}", String::from_utf8_lossy(&replotted.stderr));
    for file in ["cal.svg", "again.svg"] {
        let svg = std::fs::read_to_string(dir.path().join(file)).unwrap();
        let doc = parse(&svg);
        let bars: Vec<f64> = doc
            .descendants()
            .filter(|n| n.has_tag_name("rect") && n.attribute("class") == Some("rms-bar"))
            .map(|n| n.attribute("height").unwrap().parse().unwrap())
            .collect();
        let positions = stages.iter().flat_map(|s| [&s["fit"], &s["check"]]);
        let orientations = stages.iter().flat_map(|s| [&s["orientation"][0], &s["orientation"][1]]);
        let panels: Vec<Vec<f64>> = [positions.collect::<Vec<_>>(), orientations.collect()]
            .map(|p| p.iter().map(|e| e["rms"].as_f64().unwrap()).collect())
            .into();
        assert_eq!(bars.len(), panels[0].len() + panels[1].len(), "{file}");
        for (heights, rms) in [&bars[..panels[0].len()], &bars[panels[0].len()..]].iter().zip(&panels) {
            for (h, r) in heights.iter().zip(rms) {
                assert!(
                    (h / heights[0] - r / rms[0]).abs() < 1e-3,
                    "{file}: bar {h} px for {r} (first {} px for {})",
                    heights[0],
                    rms[0]
                );
            }
        }
        let t = texts(&doc);
        assert!(t.iter().any(|x| x == "position error [mm]"), "{t:?}");
        assert!(t.iter().any(|x| x == "orientation error [mrad]"), "{t:?}");
        assert!(t.iter().any(|x| x.starts_with("+ joint-offset:J2")), "{t:?}");
        assert_no_text_overlaps(&svg, file);
    }
}

/// A PNG's labels are glyph outlines placed as SVG places text: a label anchored at its middle has its ink
/// centred on its x (within a pixel: the side bearings of its first and last glyphs), one anchored at its
/// end ends there, one at its start begins there, each sitting on its baseline (DejaVu Sans's digits reach 0.74 em
/// above it, and the round foot of a 0 dips 0.014 em below); rotation and halo paint are kept; no `<text>`
/// is left for a renderer without fonts.
#[test]
fn png_labels_are_outlines_placed_where_svg_places_text() {
    use stiff::plot::glyphs::Font;
    use stiff::plot::raster::text_as_outlines;
    let font = Font::parse(dejavu::sans::regular()).unwrap();
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="400" height="100">
<text x="200" y="50" font-size="20" text-anchor="middle">1200</text>
<text x="200" y="80" font-size="10" text-anchor="end" transform="rotate(-90 200 80)">0.5</text>
<text x="20" y="30" font-size="10" stroke="white" stroke-width="3" paint-order="stroke">x &amp; 8</text>
</svg>"#;
    let outlined = text_as_outlines(svg, &font).unwrap();
    let doc = parse(&outlined);
    assert_eq!(doc.descendants().filter(|n| n.has_tag_name("text")).count(), 0);
    let paths: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("path")).collect();
    assert_eq!(paths.len(), 3);
    let extent = |d: &str| {
        let v: Vec<f64> =
            d.split(|c: char| c.is_ascii_alphabetic() || c == ' ').filter_map(|t| t.parse().ok()).collect();
        let (xs, ys): (Vec<f64>, Vec<f64>) =
            (v.iter().step_by(2).copied().collect(), v.iter().skip(1).step_by(2).copied().collect());
        let lo = |s: &[f64]| s.iter().copied().fold(f64::MAX, f64::min);
        let hi = |s: &[f64]| s.iter().copied().fold(f64::MIN, f64::max);
        (lo(&xs), hi(&xs), lo(&ys), hi(&ys))
    };
    let (x0, x1, y0, y1) = extent(paths[0].attribute("d").unwrap());
    assert!(((x0 + x1) / 2.0 - 200.0).abs() < 1.0, "centred: {x0} .. {x1}");
    assert!((y1 - 50.0).abs() < 0.5 && (50.0 - y0 - 0.74 * 20.0).abs() < 0.5, "on its baseline: {y0} .. {y1}");
    let (_, end, _, _) = extent(paths[1].attribute("d").unwrap());
    assert!(end < 200.0 && end > 199.0, "ends at its anchor: {end}");
    assert_eq!(paths[1].attribute("transform"), Some("rotate(-90 200 80)"));
    let (start, _, _, _) = extent(paths[2].attribute("d").unwrap());
    assert!(start > 20.0 && start < 21.5, "starts at its anchor: {start}");
    assert_eq!(
        (paths[2].attribute("stroke"), paths[2].attribute("paint-order")),
        (Some("white"), Some("stroke")),
        "the halo is kept"
    );
}
