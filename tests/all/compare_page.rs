//! `poa preview --compare ORIGINAL FILE -o DIR`: one HTML page with a layer slider, both
//! files' layers side by side, opened in headless Chromium as a user would open it.

use std::path::Path;

use crate::common::{have, poa, poa_to, sample};

/// The `(layer, in air before, in air after)` of every pair on the page.
fn pairs(page: &str) -> Vec<(usize, f64, f64)> {
    page.split("<div class=\"pair\" data-layer=\"")
        .skip(1)
        .map(|rest| {
            let layer = rest[..rest.find('"').unwrap()].parse().unwrap();
            let air = rest.split("data-in-air=\"").nth(1).unwrap();
            let air = &air[..air.find('"').unwrap()];
            let (a, b) = air.split_once(' ').unwrap();
            (layer, a.parse().unwrap(), b.parse().unwrap())
        })
        .collect()
}

/// The page's DOM after its script ran, by headless Chromium; `None` (skipped) without it.
fn chromium_dom(page: &Path, query: &str) -> Option<String> {
    if !have("chromium", &["--version"], "apt-get install -y chromium") {
        return None;
    }
    let profile = tempfile::tempdir().unwrap();
    let o = std::process::Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("--dump-dom")
        .arg(format!("file://{}{query}", page.display()))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    Some(String::from_utf8(o.stdout).unwrap())
}

#[test]
fn the_compare_page_shows_the_rewritten_layer_and_the_one_above_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    let original = sample("rect_overhang_prusa_rel.gcode");
    let rewritten = dir.path().join("poa.gcode");
    assert!(poa_to("process", &original, &rewritten, &[])
        .status
        .success());
    let out = dir.path().join("cmp");
    let o = poa()
        .args(["preview", "--compare"])
        .arg(&original)
        .arg(&rewritten)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let index = out.join("index.html");
    let page = std::fs::read_to_string(&index).unwrap();
    // The first floating layer (51 at Z 10.2) and the layer above; the rewrite leaves
    // almost nothing in air where the slice left most of the overhang.
    let p = pairs(&page);
    assert_eq!(
        p.iter().map(|x| x.0).collect::<Vec<_>>(),
        vec![51, 52],
        "{p:?}"
    );
    let (_, before, after) = p[0];
    assert!(before > 1000.0 && after < 3.0, "{p:?}");
    assert!(p[1].2 <= p[1].1 + 0.5, "layer above worse: {p:?}");
    // Two SVGs per pair, and poa's loops drawn in their own shades.
    assert_eq!(page.matches("<svg").count(), 4);
    assert!(page.contains("poa loops, first to last") && page.contains("#49006a"));

    // Opened in a browser: the script runs, shows one pair, and a link to a layer opens it.
    let Some(dom) = chromium_dom(&index, "") else {
        return;
    };
    assert!(dom.contains("data-ready=\"1\"") && dom.contains("data-shown=\"51\""));
    assert_eq!(dom.matches("class=\"pair\"").count(), 2);
    assert_eq!(dom.matches(" hidden=\"\"").count(), 1, "one pair hidden");
    let dom = chromium_dom(&index, "?layer=52").unwrap();
    assert!(dom.contains("data-shown=\"52\""));
    assert!(
        dom.contains("layer 52 at Z 10.400 mm: in air"),
        "label not set"
    );
}

#[test]
fn identical_files_make_a_page_that_says_so_and_inputs_are_never_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let original = sample("circ_overhang_prusa_rel.gcode");
    let out = dir.path().join("same");
    let o = poa()
        .args(["preview", "--compare"])
        .arg(&original)
        .arg(&original)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(page.contains("0 of ") && page.contains("print the same strands"));
    assert!(pairs(&page).is_empty());
    // -o naming an input file is refused.
    let o = poa()
        .args(["preview", "--compare"])
        .arg(&original)
        .arg(sample("rect_overhang_prusa_rel.gcode"))
        .arg("-o")
        .arg(&original)
        .output()
        .unwrap();
    assert!(!o.status.success());
}
