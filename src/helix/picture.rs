//! Pictures of a layer-less print: a side profile (distance from the axis against height,
//! each sampled bead drawn at its width and height) and a top view, unsupported points red.
//!
//! Input: the judged samples of a [`Report`] and the helix's axis. Output: SVG text, and an
//! HTML page holding both with the check's summary.

use crate::helix::printable::{Bead, Report};
use crate::preview::escape;

const SIZE: f64 = 480.0;

fn frame(points: impl Iterator<Item = [f64; 2]>) -> ([f64; 2], [f64; 2]) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in points {
        for i in 0..2 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    if !lo[0].is_finite() {
        return ([0.0; 2], [1.0; 2]);
    }
    (lo, hi)
}

fn svg(title: &str, pts: &[([f64; 2], bool)], bead: [f64; 2], flip_y: bool) -> String {
    let (lo, hi) = frame(pts.iter().map(|p| p.0));
    let pad = 2.0;
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0) + 2.0 * pad;
    let k = SIZE / span;
    let tx = |x: f64| (x - lo[0] + pad) * k;
    let ty = |y: f64| {
        if flip_y {
            SIZE - (y - lo[1] + pad) * k
        } else {
            (y - lo[1] + pad) * k
        }
    };
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{SIZE}\" height=\"{SIZE}\" viewBox=\"0 0 {SIZE} {SIZE}\">\n<title>{}</title>\n<rect width=\"100%\" height=\"100%\" fill=\"#fafafa\"/>\n",
        escape(title)
    );
    let (w, h) = ((bead[0] * k).max(0.6), (bead[1] * k).max(0.6));
    // Supported points first, red ones on top so they are never hidden.
    for red in [false, true] {
        for (p, ok) in pts.iter().filter(|(_, ok)| *ok != red) {
            let _ = ok;
            s.push_str(&format!(
                "<ellipse cx=\"{:.2}\" cy=\"{:.2}\" rx=\"{:.2}\" ry=\"{:.2}\" fill=\"{}\"/>\n",
                tx(p[0]),
                ty(p[1]),
                w / 2.0,
                h / 2.0,
                if red { "#d62728" } else { "#1f77b4" }
            ));
        }
    }
    s.push_str(&format!(
        "<text x=\"6\" y=\"16\" font-family=\"sans-serif\" font-size=\"13\">{}</text>\n</svg>\n",
        escape(title)
    ));
    s
}

/// Side profile: distance from the axis (right) against height (up).
pub fn profile_svg(report: &Report, center: [f64; 2], bead: Bead) -> String {
    let pts: Vec<([f64; 2], bool)> = report
        .samples
        .iter()
        .map(|s| {
            (
                [(s.p[0] - center[0]).hypot(s.p[1] - center[1]), s.p[2]],
                s.ok,
            )
        })
        .collect();
    svg(
        "side profile: r (mm) against z (mm)",
        &pts,
        [bead.width, bead.height],
        true,
    )
}

/// Top view.
pub fn top_svg(report: &Report, bead: Bead) -> String {
    let pts: Vec<([f64; 2], bool)> = report
        .samples
        .iter()
        .map(|s| ([s.p[0], s.p[1]], s.ok))
        .collect();
    svg("top view", &pts, [bead.width, bead.width], true)
}

/// An HTML page with both pictures and the check's numbers.
pub fn page(title: &str, report: &Report, center: [f64; 2], bead: Bead) -> String {
    let verdict = match &report.first {
        None => "every point rests on earlier material; no collision".to_string(),
        Some(f) => format!("first failing point: {f}"),
    };
    format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>body{{font-family:sans-serif;margin:1em}} figure{{display:inline-block;margin:0 1em 1em 0}}</style></head><body>\n<h1>{t}</h1>\n<p>{v}</p>\n<p>{n} points judged over {turns:.1} turns: {u} unsupported, {c} collisions, {l} lift out of range, {st} too steep; largest lean {lean:.1} deg.</p>\n<figure>{p}<figcaption>side profile (red: breaks a rule)</figcaption></figure>\n<figure>{top}<figcaption>top view</figcaption></figure>\n</body></html>\n",
        t = escape(title),
        v = escape(&verdict),
        n = report.points,
        turns = report.turns,
        u = report.unsupported,
        c = report.collisions,
        l = report.lift_out_of_range,
        st = report.too_steep,
        lean = report.max_lean_deg,
        p = profile_svg(report, center, bead),
        top = top_svg(report, bead),
    )
}

/// The pictures of a layer-less file as `poa preview` draws them.
pub struct Pictures {
    pub page: String,
    pub profile: String,
    pub top: String,
    pub report: Report,
}

/// Judges the layer-less print `text` and draws it; `None` when `text` is not one (no
/// helix: the layered preview applies).
pub fn layerless(
    text: &[u8],
    config: &crate::layers::SlicerConfig,
    title: &str,
) -> Option<Pictures> {
    layerless_in(text, config, title).ok().flatten()
}

/// [`layerless`] of the print `src` reads (a file a line at a time); a read error as it is.
pub fn layerless_in<S: crate::helix::Source + ?Sized>(
    src: &S,
    config: &crate::layers::SlicerConfig,
    title: &str,
) -> Result<Option<Pictures>, crate::error::Error> {
    let helix = match crate::helix::find_in(src) {
        Ok(h) => h,
        Err(crate::error::Error::Refused(_)) => return Ok(None),
        Err(e) => return Err(e),
    };
    let bead = crate::helix::bead_of(config, &helix);
    let report = crate::helix::printable::check_in(src, &helix, bead, 20_000)?;
    Ok(Some(Pictures {
        page: page(title, &report, helix.center, bead),
        profile: profile_svg(&report, helix.center, bead),
        top: top_svg(&report, bead),
        report,
    }))
}
