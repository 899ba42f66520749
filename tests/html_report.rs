//! `report.html` in a real browser: headless Chromium (Debian's package; `scripts/test`
//! installs it when missing) loads the page of a small run folder from `file://` with the
//! network unused, draws the map and the vehicles, reports no script error, and the replay
//! advances when played. Without Chromium the test says so and passes, unless
//! `CPMX_REQUIRE_CHROMIUM` is set (as `scripts/test` does).

use std::path::{Path, PathBuf};
use std::process::Command;

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

/// The value of `name="..."` on the page's `<body>`.
fn body_attribute(dom: &str, name: &str) -> Option<String> {
    let body = &dom[dom.find("<body")?..];
    let tag = &body[..body.find('>')?];
    let start = tag.find(&format!("{name}=\""))? + name.len() + 2;
    Some(tag[start..start + tag[start..].find('"')?].to_owned())
}

#[test]
fn the_report_page_renders_and_replays_in_chromium() {
    let Some(browser) = chromium() else {
        assert!(
            std::env::var_os("CPMX_REQUIRE_CHROMIUM").is_none(),
            "Chromium is required (CPMX_REQUIRE_CHROMIUM) but not installed"
        );
        eprintln!("skipped: no Chromium (install Debian's `chromium`, or run scripts/test)");
        return;
    };
    let dir = std::env::temp_dir().join(format!("cpmx-html-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["run", "examples/sim-to-twin.yaml", "--out", out.to_str().unwrap()])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));

    // One self-contained file: nothing to fetch.
    let page = out.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.len() < 5_000_000, "{} bytes", html.len());
    for external in ["src=\"http", "href=\"http", "<link", "url(http", "import("] {
        assert!(!html.contains(external), "the page refers to `{external}`");
    }

    // Load it, let the replay play, and read back what the page drew.
    let url = format!("file://{}#autoplay", page.display());
    let dom = headless(
        &browser,
        &dir.join("profile-dom"),
        &["--virtual-time-budget=4000", "--dump-dom", &url],
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
    let screenshot = dir.join("report.png");
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
    std::fs::remove_dir_all(&dir).ok();
}
