//! `report.html` in a real browser: headless Chromium (Debian's package; `scripts/test`
//! installs it when missing) loads the page of a small run folder from `file://` with the
//! network unused, draws the map and the vehicles, reports no script error, and the replay
//! advances when played; at a 1,400 px and a 600 px window the figures use the page's width
//! (as the page measures them) and the canvases match the screen's resolution; a folder whose
//! configurations drive on two maps has each run drawn on its own. Without
//! Chromium the tests say so and pass, unless `CPMX_REQUIRE_CHROMIUM` is set (as
//! `scripts/test` does).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn chromium() -> Option<PathBuf> {
    [
        "/usr/bin/chromium",
        "/usr/bin/chromium-browser",
        "/usr/bin/google-chrome",
    ]
    .into_iter()
    .map(PathBuf::from)
    .find(|p| p.is_file())
}

/// Chromium, or `None` (after saying so) when it is missing and not required.
fn browser() -> Option<PathBuf> {
    let browser = chromium();
    if browser.is_none() {
        assert!(
            std::env::var_os("CPMX_REQUIRE_CHROMIUM").is_none(),
            "Chromium is required (CPMX_REQUIRE_CHROMIUM) but not installed"
        );
        eprintln!("skipped: no Chromium (install Debian's `chromium`, or run scripts/test)");
    }
    browser
}

/// The run folder of `examples/sim-to-twin.yaml` (built-in intersection, one policy, three
/// fidelities) with the twin's actuation delay swept over three values (so the page has
/// sensitivity curves), written once for all tests of this file into the target's temporary
/// folder, where its page and the screenshots stay for people to look at.
fn folder() -> &'static Path {
    static FOLDER: OnceLock<PathBuf> = OnceLock::new();
    FOLDER.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("html-report");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let example = std::fs::read_to_string(root().join("examples/sim-to-twin.yaml")).unwrap();
        let swept = example.replace(
            "actuation: {delay_ms: 80}",
            "actuation: {delay_ms: {sweep: [40, 80, 120]}}",
        );
        assert_ne!(swept, example, "the example's twin has an actuation delay");
        let spec = dir.join("sim-to-twin-swept.yaml");
        std::fs::write(&spec, swept).unwrap();
        let out = dir.join("out");
        let run = Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .args(["run", spec.to_str().unwrap(), "--out", out.to_str().unwrap()])
            .current_dir(root())
            .output()
            .unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        dir
    })
}

/// Chromium headless with a fresh profile and no background network.
fn headless(browser: &Path, profile: &Path, args: &[&str]) -> std::process::Output {
    Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-dev-shm-usage",
            &format!("--user-data-dir={}", profile.display()),
        ])
        .args(args)
        .output()
        .expect("chromium starts")
}

/// The page at `url` after its script ran (4 s of virtual time), as Chromium's DOM, asserting
/// that the script ran to its end without an error.
fn loaded_dom(browser: &Path, profile: &Path, url: &str) -> String {
    let dom = headless(
        browser,
        profile,
        &["--virtual-time-budget=4000", "--dump-dom", url],
    );
    let dom = String::from_utf8_lossy(&dom.stdout).into_owned();
    assert_eq!(
        body_attribute(&dom, "data-ready").as_deref(),
        Some("1"),
        "the script ran to its end"
    );
    assert_eq!(
        body_attribute(&dom, "data-errors"),
        None,
        "script errors: {dom:.2000}"
    );
    dom
}

/// The value of `name="..."` on the page's `<body>`.
fn body_attribute(dom: &str, name: &str) -> Option<String> {
    let body = &dom[dom.find("<body")?..];
    let tag = &body[..body.find('>')?];
    let start = tag.find(&format!("{name}=\""))? + name.len() + 2;
    Some(tag[start..start + tag[start..].find('"')?].to_owned())
}

#[test]
fn the_report_page_renders_and_replays_in_chromium() {
    let Some(browser) = browser() else {
        return;
    };
    let dir = folder();
    let out = dir.join("out");

    // One self-contained file: nothing to fetch.
    let page = out.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.len() < 5_000_000, "{} bytes", html.len());
    for external in ["src=\"http", "href=\"http", "<link", "url(http", "import("] {
        assert!(!html.contains(external), "the page refers to `{external}`");
    }

    // Load it, let the replay play, and read back what the page drew.
    let url = format!("file://{}#autoplay", page.display());
    let dom = loaded_dom(&browser, &dir.join("profile-dom"), &url);
    let pixels: usize = body_attribute(&dom, "data-vehicle-pixels")
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        pixels > 200,
        "vehicles and paths drawn in colour: {pixels} pixels"
    );
    let frame: usize = body_attribute(&dom, "data-replay-frame")
        .unwrap()
        .parse()
        .unwrap();
    assert!(frame > 0, "the replay advanced");
    assert!(
        dom.contains("initial configuration "),
        "Figure 3 per initial configuration"
    );
    assert!(
        dom.matches("<canvas").count() >= 4,
        "setup, representatives and replay panels"
    );

    // A screenshot for people (kept beside the folder); it must be a real PNG.
    let screenshot = dir.join("report-autoplay.png");
    headless(
        &browser,
        &dir.join("profile-shot"),
        &[
            "--window-size=1400,2400",
            &format!("--screenshot={}", screenshot.display()),
            &format!("file://{}", page.display()),
        ],
    );
    let png = std::fs::read(&screenshot).expect("chromium wrote the screenshot");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 20_000,
        "{} bytes",
        png.len()
    );
}

/// A figure of the page as the page measured it (CSS pixels).
#[derive(Debug)]
struct Figure {
    section: String,
    left: i64,
    top: i64,
    width: i64,
    /// The width of its canvas or SVG.
    drawing: i64,
}

/// What the page measured of its layout in a `width_px` wide window at `scale` device pixels
/// per CSS pixel: the viewport's width, how far it overflows sideways, the least resolution of
/// its canvases, and its figures.
struct Layout {
    viewport: i64,
    overflow: i64,
    /// How far the widest table reaches past its box (0: every column on screen).
    table_overflow: i64,
    /// The smallest text of any figure's SVG as drawn [CSS px].
    smallest_figure_text_px: f64,
    canvas_scale: f64,
    figures: Vec<Figure>,
    /// The text of every figure's caption.
    captions: Vec<String>,
}

fn layout(browser: &Path, page: &Path, width_px: u32, scale: u32) -> Layout {
    let profile = folder().join(format!("profile-layout-{width_px}"));
    let dom = headless(
        browser,
        &profile,
        &[
            &format!("--window-size={width_px},1000"),
            &format!("--force-device-scale-factor={scale}"),
            "--hide-scrollbars",
            "--virtual-time-budget=1000",
            "--dump-dom",
            &format!("file://{}", page.display()),
        ],
    );
    let dom = String::from_utf8_lossy(&dom.stdout).into_owned();
    assert_eq!(
        body_attribute(&dom, "data-ready").as_deref(),
        Some("1"),
        "{dom:.2000}"
    );
    assert_eq!(
        body_attribute(&dom, "data-errors"),
        None,
        "script errors: {dom:.2000}"
    );
    let number = |name: &str| -> f64 {
        body_attribute(&dom, name)
            .unwrap_or_else(|| panic!("the page wrote {name}"))
            .parse()
            .unwrap()
    };
    let figures = body_attribute(&dom, "data-figures")
        .unwrap()
        .split(';')
        .map(|figure| {
            let fields: Vec<&str> = figure.split(' ').collect();
            let [section, left, top, width, drawing] = fields[..] else {
                panic!("a figure's measure: `{figure}`");
            };
            Figure {
                section: section.to_owned(),
                left: left.parse().unwrap(),
                top: top.parse().unwrap(),
                width: width.parse().unwrap(),
                drawing: drawing.parse().unwrap(),
            }
        })
        .collect();
    let captions = dom
        .split("<figcaption>")
        .skip(1)
        .map(|rest| rest[..rest.find("</figcaption>").unwrap_or(rest.len())].to_owned())
        .collect();
    Layout {
        captions,
        viewport: number("data-viewport-width") as i64,
        overflow: number("data-overflow-x") as i64,
        table_overflow: number("data-table-overflow-x") as i64,
        smallest_figure_text_px: number("data-smallest-figure-text-px"),
        canvas_scale: number("data-canvas-scale"),
        figures,
    }
}

/// The figures of each section in rows: (section, top) → the figures' (left, width).
fn rows(figures: &[Figure]) -> BTreeMap<(&str, i64), Vec<(i64, i64)>> {
    let mut rows: BTreeMap<(&str, i64), Vec<(i64, i64)>> = BTreeMap::new();
    for f in figures {
        rows.entry((f.section.as_str(), f.top))
            .or_default()
            .push((f.left, f.width));
    }
    rows
}

/// The PNG's width and height, from its header.
fn png_size(png: &[u8]) -> (u32, u32) {
    assert!(png.starts_with(b"\x89PNG") && png.len() > 24, "a PNG");
    let word = |at: usize| u32::from_be_bytes(png[at..at + 4].try_into().unwrap());
    (word(16), word(20))
}

#[test]
fn the_report_page_uses_the_width_of_a_wide_and_of_a_narrow_window() {
    let Some(browser) = browser() else {
        return;
    };
    let page = folder().join("out/report.html");

    // A 1,400 px window on a screen of two device pixels per CSS pixel: figures side by side,
    // each at least 400 px wide, the rows filling the page, canvases at the screen's resolution.
    let wide = layout(&browser, &page, 1400, 2);
    assert_eq!(wide.viewport, 1400, "the window's width");
    assert_eq!(wide.overflow, 0, "nothing wider than the window");
    assert!(
        wide.canvas_scale >= 1.99,
        "canvases drawn at 2 px per CSS px: {}",
        wide.canvas_scale
    );
    let sections = ["figure3", "replay", "sensitivity", "distributions"];
    for section in sections {
        assert!(
            wide.figures.iter().filter(|f| f.section == section).count() >= 2,
            "figures in {section}: {:?}",
            wide.figures
        );
    }
    for f in &wide.figures {
        assert!(f.width >= 400, "a figure {} px wide at 1,400 px: {f:?}", f.width);
        assert!(
            f.drawing >= f.width - 40,
            "a drawing narrower than its figure: {f:?}"
        );
    }
    // Figures share rows (two or three a row); a figure alone in its row is a wide one (two
    // columns or more: a distribution of many groups) or the last of its section.
    let rows_wide = rows(&wide.figures);
    for section in ["figure3", "replay", "sensitivity"] {
        let shared = rows_wide
            .iter()
            .filter(|((s, _), row)| *s == section && row.len() >= 2)
            .count();
        assert!(
            shared >= 1,
            "no two figures of {section} share a row: {rows_wide:?}"
        );
    }
    for ((section, top), row) in &rows_wide {
        let last = rows_wide
            .keys()
            .filter(|(s, _)| s == section)
            .all(|(_, t)| t <= top);
        assert!(
            row.len() >= 2 || row[0].1 as f64 >= 0.6 * wide.viewport as f64 || last,
            "a figure of {section} alone in its row at a third of the page: {rows_wide:?}"
        );
    }
    let widest = rows_wide
        .values()
        .map(|row| {
            let left = row.iter().map(|&(l, _)| l).min().unwrap();
            let right = row.iter().map(|&(l, w)| l + w).max().unwrap();
            right - left
        })
        .max()
        .unwrap();
    assert!(
        widest as f64 >= 0.85 * wide.viewport as f64,
        "the widest row of figures spans {widest} of {} px",
        wide.viewport
    );

    // Figures' text is readable where they are drawn: none below 10 px.
    assert!(
        wide.smallest_figure_text_px >= 10.0,
        "a figure's text drawn at {} px at 1,400 px",
        wide.smallest_figure_text_px
    );

    // Every figure says whose runs it shows: the folder's one policy, by name.
    assert_eq!(wide.captions.len(), wide.figures.len(), "{:?}", wide.captions);
    for caption in &wide.captions {
        assert!(
            caption.contains("baseline"),
            "a caption without its policy: {caption}"
        );
    }

    // A phone's 600 px: one figure a row, each nearly the page's width.
    let narrow = layout(&browser, &page, 600, 1);
    assert_eq!(narrow.viewport, 600, "the window's width");
    assert_eq!(narrow.overflow, 0, "nothing wider than the window");
    assert_eq!(
        narrow.table_overflow, 0,
        "a table scrolls sideways at 600 px (its last columns off screen)"
    );
    assert!(narrow.canvas_scale >= 0.99, "{}", narrow.canvas_scale);
    assert_eq!(narrow.figures.len(), wide.figures.len());
    for f in &narrow.figures {
        assert!(
            f.width as f64 >= 0.9 * narrow.viewport as f64,
            "a figure {} px wide at 600 px: {f:?}",
            f.width
        );
        assert!(
            f.drawing >= f.width - 40,
            "a drawing narrower than its figure: {f:?}"
        );
    }
    assert!(
        rows(&narrow.figures).values().all(|row| row.len() == 1),
        "one figure a row at 600 px"
    );

    // Screenshots at both widths, kept beside the folder for people.
    for (width_px, height_px) in [(1400, 3000), (600, 4000)] {
        let screenshot = folder().join(format!("report-{width_px}.png"));
        headless(
            &browser,
            &folder().join(format!("profile-shot-{width_px}")),
            &[
                &format!("--window-size={width_px},{height_px}"),
                "--hide-scrollbars",
                &format!("--screenshot={}", screenshot.display()),
                &format!("file://{}", page.display()),
            ],
        );
        let png = std::fs::read(&screenshot).expect("chromium wrote the screenshot");
        assert_eq!(png_size(&png), (width_px, height_px), "{}", screenshot.display());
    }
}

/// A folder whose configurations drive on two maps (the CPM map and SigmaRL's `roundabout_1`,
/// from SigmaRL's reference data): the page draws each run on its own map, so the panels of
/// the roundabout's runs keep its 3.5 m × 2.0 m shape and the CPM map's stay nearly square,
/// and no script fails.
#[test]
fn the_report_page_draws_each_run_on_its_map_and_agents_that_come_and_go() {
    let Some(browser) = browser() else {
        return;
    };
    let reference = cpmx_testdata::reference();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("html-report-maps");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let spec = dir.join("two-maps.yaml");
    std::fs::write(
        &spec,
        "cpmx: 1
name: two-maps
map: {file: maps/cpm.xml, tag: 1.2.0}
vehicle: {length: 0.16, width: 0.08, wheelbase: 0.16, rear_axle: 0.08, max_steering_deg: 35, max_steering_rate_deg_s: 900, accel: [-20, 20], max_speed: 1.0}
timing: {dt: 0.05, steps: 200}
agents: 4
policies:
  - {name: m0, mlp: {sigmarl: sigmarl-published/checkpoints/itsc24/M0, tag: 1.2.0}}
initial_configurations:
  - {name: cpm, sample: {count: 1, seed: 3, min_gap: 0.22}}
  - {name: roundabout, map: {sigmarl: roundabout_1}, sample: {count: 1, seed: 3, min_gap: 0.22}}
repetitions: 1
seed: 3
on_collision: replace-agent
fidelities:
  sim: {control: direct, dynamics: kinematic-vmas}
",
    )
    .unwrap();
    let out = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args([
            "run",
            spec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--data",
        ])
        .arg(&reference)
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    // Cars that reach their path's end are replaced: agents come and go in the replay.
    let per_run = std::fs::read_to_string(out.join("per_run.csv")).unwrap();
    let agents_col = per_run
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|h| h == "num_agents")
        .unwrap();
    assert!(
        per_run
            .lines()
            .skip(1)
            .any(|l| l.split(',').nth(agents_col).unwrap().parse::<usize>().unwrap() > 4),
        "{per_run}"
    );
    let url = format!("file://{}#autoplay", out.join("report.html").display());
    let dom = loaded_dom(&browser, &dir.join("profile"), &url);
    let aspects: Vec<f64> = dom
        .split("aspect-ratio: ")
        .skip(1)
        .map(|rest| {
            // `aspect-ratio: 1.5585 / 1;`
            let value = &rest[..rest.find([' ', ';', '"']).unwrap()];
            value.parse().unwrap()
        })
        .collect();
    assert!(
        aspects.iter().any(|&a| a > 1.4),
        "a roundabout panel: {aspects:?}"
    );
    assert!(aspects.iter().any(|&a| a < 1.2), "a CPM map panel: {aspects:?}");
}
