//! Pictures of what poa sees: one SVG per layer.
//!
//! Input: a layer, the printed area below it and the layer's regions (from
//! [`crate::geometry`]). Output: a self-contained SVG drawn in millimetres: the area below in
//! grey, the layer's strands at their real width coloured by role, the regions outlined and
//! numbered by kind, a millimetre grid with labels, a scale bar and a legend. For
//! `poa preview --regions`, an `index.html` lists every region with a link to its layer.
//!
//! The picture is G-code's view from above: +Y points up (SVG's Y axis is flipped here).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::io::{self, BufRead};

use geo::{BoundingRect, LineString, MultiPolygon, Polygon};

use crate::geometry::{self, DetectOptions, Region, RegionKind};
use crate::layers::{Layer, LayerKind, LayerReader, Path, ReaderOptions, Role, SlicerConfig};

/// What to draw.
pub struct Scene<'a> {
    pub title: &'a str,
    pub layer: &'a Layer,
    pub below: &'a MultiPolygon<f64>,
    /// Regions with their file-wide numbers.
    pub regions: &'a [(usize, &'a Region)],
    /// Deposition check samples to mark (bridged and in-air ones), from `poa check`.
    pub samples: &'a [crate::check::Sample],
    /// Line ranges of the blocks poa wrote ([`poa_blocks`]): their strands are drawn in
    /// poa's colour, shaded by order.
    pub poa_blocks: &'a [(u64, u64)],
}

/// Line ranges (first, last, inclusive) of the blocks poa wrote in `layer`
/// (`;POA_BEGIN` .. `;POA_END`), read from its raw bytes (empty without `keep_raw`).
pub fn poa_blocks(layer: &Layer) -> Vec<(u64, u64)> {
    let mut v = Vec::new();
    let mut open = None;
    for (i, line) in layer.raw.split(|&b| b == b'\n').enumerate() {
        let n = layer.first_line + i as u64;
        if line.starts_with(b";POA_BEGIN") {
            open = Some(n);
        } else if line.starts_with(b";POA_END") {
            if let Some(first) = open.take() {
                v.push((first, n));
            }
        }
    }
    v
}

/// poa's loops: darkest first (at the supported edge), lightest last (outermost).
const POA_FIRST: [u8; 3] = [0x49, 0x00, 0x6a];
const POA_LAST: [u8; 3] = [0xf7, 0x68, 0xa1];

/// Colour of the `k`-th of `n` strands of a poa block.
fn poa_shade(k: usize, n: usize) -> String {
    let t = if n > 1 {
        k as f64 / (n - 1) as f64
    } else {
        0.0
    };
    let c: Vec<u8> = (0..3)
        .map(|i| {
            (POA_FIRST[i] as f64 + (POA_LAST[i] as f64 - POA_FIRST[i] as f64) * t).round() as u8
        })
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// For each path of `layer`: `Some((k, n))` when it is the `k`-th of the `n` strands of a
/// poa block.
fn poa_order(layer: &Layer, blocks: &[(u64, u64)]) -> Vec<Option<(usize, usize)>> {
    let block_of = |p: &Path| {
        let line = *p.seg_line.first()?;
        blocks.iter().position(|(a, b)| (*a..=*b).contains(&line))
    };
    let which: Vec<Option<usize>> = layer.paths.iter().map(block_of).collect();
    let mut seen = vec![0usize; blocks.len()];
    let mut count = vec![0usize; blocks.len()];
    for b in which.iter().flatten() {
        count[*b] += 1;
    }
    which
        .iter()
        .map(|b| {
            b.map(|b| {
                seen[b] += 1;
                (seen[b] - 1, count[b])
            })
        })
        .collect()
}

/// Colour of a role; close to the slicer previews users know.
pub fn role_color(role: Role) -> &'static str {
    match role {
        Role::ExternalPerimeter => "#ff7d38",
        Role::Perimeter => "#e6c229",
        Role::OverhangPerimeter => "#1f3fff",
        Role::Infill => "#b03029",
        Role::SolidInfill => "#9654cc",
        Role::TopSolid => "#f04040",
        Role::BridgeInfill => "#4d80ba",
        Role::InternalBridge => "#79a7d9",
        Role::GapFill => "#2e9e5b",
        Role::Support => "#3cb371",
        Role::SupportInterface => "#20b2aa",
        Role::SkirtBrim => "#00876e",
        Role::WipePrime => "#a3d39c",
        Role::Custom => "#5ed194",
        Role::Unknown => "#555555",
    }
}

fn region_color(kind: RegionKind) -> &'static str {
    match kind {
        RegionKind::Overhang => "#d7191c",
        RegionKind::Bridge => "#7b1fa2",
        RegionKind::Floating => "#212121",
    }
}

/// Pixels per millimetre of the drawing's nominal size.
const PX_PER_MM: f64 = 14.0;
const LEGEND_W: f64 = 46.0;

/// Renders one layer as SVG text.
///
/// Long by design: one pass over the layers that draws the three views and the legend with shared scales and colours; the drawing helpers it calls are the reusable parts.
pub fn render(scene: &Scene<'_>) -> String {
    // Drawing bounds: the strands, the area below and the regions.
    let mut bb = Bounds::default();
    for p in &scene.layer.paths {
        for q in &p.points {
            bb.add(q[0], q[1]);
        }
    }
    for poly in &scene.below.0 {
        if let Some(r) = poly.bounding_rect() {
            bb.add(r.min().x, r.min().y);
            bb.add(r.max().x, r.max().y);
        }
    }
    if bb.empty() {
        bb.add(0.0, 0.0);
        bb.add(10.0, 10.0);
    }
    let margin = 4.0;
    let (x0, y0) = ((bb.x0 - margin).floor(), (bb.y0 - margin).floor());
    let (x1, y1) = ((bb.x1 + margin).ceil(), (bb.y1 + margin).ceil());
    let (w, h) = (x1 - x0, y1 - y0);
    let header = 9.0;
    let footer = 4.0;
    let total_w = w + LEGEND_W;
    let total_h = (h + header + footer).max(legend_height(scene) + header);
    // Map G-code (x, y) to SVG: y flipped, drawing below the header.
    let tx = |x: f64| x - x0;
    let ty = |y: f64| header + (y1 - y);
    let font = (w.max(h) / 70.0).clamp(1.2, 3.0);

    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" viewBox="0 0 {total_w:.3} {total_h:.3}" font-family="Helvetica, Arial, sans-serif">"#,
        total_w * PX_PER_MM,
        total_h * PX_PER_MM
    );
    let _ = writeln!(
        s,
        r#"<rect x="0" y="0" width="{total_w:.3}" height="{total_h:.3}" fill="white"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="1" y="{:.2}" font-size="{:.2}" font-weight="bold">{}</text>"#,
        header * 0.45,
        (header * 0.32).min(3.2),
        escape(scene.title)
    );
    let what = if scene.samples.is_empty() {
        format!(
            "{} region{} over air",
            scene.regions.len(),
            if scene.regions.len() == 1 { "" } else { "s" }
        )
    } else {
        let sum = |k: crate::check::Support| -> f64 {
            scene
                .samples
                .iter()
                .filter(|x| x.support == k)
                .map(|x| x.length)
                .sum()
        };
        format!(
            "deposition check: {:.1} mm bridged, {:.1} mm in air",
            sum(crate::check::Support::Bridged),
            sum(crate::check::Support::InAir)
        )
    };
    let _ = writeln!(
        s,
        r##"<text x="1" y="{:.2}" font-size="{:.2}" fill="#444">layer {} at Z {:.2} mm, {:.2} mm high; {what}</text>"##,
        header * 0.85,
        (header * 0.24).min(2.4),
        scene.layer.index + 1,
        scene.layer.z,
        scene.layer.height,
    );

    // Millimetre grid: fine lines every mm when there is room, strong every 10 mm, labelled.
    let fine = w.max(h) <= 120.0;
    let mut grid = String::new();
    let mut x = x0.ceil();
    while x <= x1 {
        let strong = (x.rem_euclid(10.0)).abs() < 1e-9;
        if strong || fine {
            let _ = write!(
                grid,
                r#"<line x1="{:.3}" y1="{:.3}" x2="{:.3}" y2="{:.3}" stroke="{}" stroke-width="{}"/>"#,
                tx(x),
                ty(y0),
                tx(x),
                ty(y1),
                if strong { "#c8c8c8" } else { "#eeeeee" },
                if strong { 0.08 } else { 0.04 }
            );
        }
        if strong {
            let _ = write!(
                grid,
                r##"<text x="{:.3}" y="{:.3}" font-size="{:.2}" fill="#888" text-anchor="middle">{x:.0}</text>"##,
                tx(x),
                ty(y0) - 0.4,
                font * 0.7
            );
        }
        x += 1.0;
    }
    let mut y = y0.ceil();
    while y <= y1 {
        let strong = (y.rem_euclid(10.0)).abs() < 1e-9;
        if strong || fine {
            let _ = write!(
                grid,
                r#"<line x1="{:.3}" y1="{:.3}" x2="{:.3}" y2="{:.3}" stroke="{}" stroke-width="{}"/>"#,
                tx(x0),
                ty(y),
                tx(x1),
                ty(y),
                if strong { "#c8c8c8" } else { "#eeeeee" },
                if strong { 0.08 } else { 0.04 }
            );
        }
        if strong {
            let _ = write!(
                grid,
                r##"<text x="{:.3}" y="{:.3}" font-size="{:.2}" fill="#888">{y:.0}</text>"##,
                tx(x0) + 0.3,
                ty(y) - 0.3,
                font * 0.7
            );
        }
        y += 1.0;
    }
    let _ = writeln!(s, "<g>{grid}</g>");

    // The area printed below.
    let _ = writeln!(
        s,
        r##"<path d="{}" fill="#bdbdbd" fill-opacity="0.55" stroke="#8a8a8a" stroke-width="0.1" fill-rule="evenodd"/>"##,
        multipolygon_path(scene.below, &tx, &ty)
    );

    // Strands at their width, by role.
    let _ = writeln!(
        s,
        r#"<g fill="none" stroke-linecap="round" stroke-linejoin="round" stroke-opacity="0.9">"#
    );
    let order = poa_order(scene.layer, scene.poa_blocks);
    for (p, order) in scene.layer.paths.iter().zip(&order) {
        if p.points.len() < 2 {
            continue;
        }
        let mut d = String::new();
        for (i, q) in p.points.iter().enumerate() {
            let _ = write!(
                d,
                "{}{:.3} {:.3}",
                if i == 0 { "M" } else { " L" },
                tx(q[0]),
                ty(q[1])
            );
        }
        let colour = match order {
            Some((k, n)) => poa_shade(*k, *n),
            None => role_color(p.role).to_string(),
        };
        let _ = writeln!(
            s,
            r#"<path d="{d}" stroke="{colour}" stroke-width="{:.3}"/>"#,
            p.width.clamp(0.05, 5.0)
        );
    }
    let _ = writeln!(s, "</g>");

    // Check results: unsupported samples as dots on the strands.
    if !scene.samples.is_empty() {
        let _ = writeln!(s, "<g>");
        for smp in scene.samples {
            let colour = match smp.support {
                crate::check::Support::Supported => continue,
                crate::check::Support::Bridged => "#f4a300",
                crate::check::Support::InAir => "#d7191c",
            };
            let _ = writeln!(
                s,
                r#"<circle cx="{:.3}" cy="{:.3}" r="0.18" fill="{colour}"/>"#,
                tx(smp.point[0]),
                ty(smp.point[1])
            );
        }
        let _ = writeln!(s, "</g>");
    }

    // Regions: tinted, outlined, numbered.
    for (id, r) in scene.regions {
        let c = region_color(r.kind);
        let d = polygon_path(&r.polygon, &tx, &ty);
        let _ = writeln!(
            s,
            r#"<path d="{d}" fill="{c}" fill-opacity="0.16" stroke="{c}" stroke-width="0.35" stroke-dasharray="1.2 0.6" fill-rule="evenodd"/>"#
        );
        if let Some(b) = r.polygon.bounding_rect() {
            let (lx, ly) = (tx(b.min().x) + 0.5, ty(b.max().y) + font * 1.3);
            let _ = writeln!(
                s,
                r#"<text x="{lx:.3}" y="{ly:.3}" font-size="{:.2}" font-weight="bold" fill="{c}" stroke="white" stroke-width="{:.2}" paint-order="stroke">#{id} {} {:.0} mm²</text>"#,
                font * 1.1,
                font * 0.25,
                r.kind.name(),
                r.area
            );
        }
    }

    // Scale bar: 10 mm (or 1 mm on tiny parts), bottom left.
    let bar = if w >= 25.0 { 10.0 } else { 1.0 };
    let (bx, by) = (tx(x0) + 1.0, ty(y0) + footer * 0.45);
    let _ = writeln!(
        s,
        r#"<g><rect x="{bx:.3}" y="{by:.3}" width="{bar}" height="0.5" fill="black"/><text x="{:.3}" y="{:.3}" font-size="{:.2}">{bar:.0} mm</text></g>"#,
        bx + bar + 0.6,
        by + 0.5,
        font * 0.8
    );

    legend(&mut s, scene, w + 1.0, header);
    s.push_str("</svg>\n");
    s
}

fn legend_height(scene: &Scene<'_>) -> f64 {
    let roles = roles_present(scene).len() as f64;
    12.0 + 3.0 * (roles + 5.0)
}

fn roles_present(scene: &Scene<'_>) -> Vec<Role> {
    let mut v: Vec<Role> = scene.layer.paths.iter().map(|p| p.role).collect();
    v.sort();
    v.dedup();
    v
}

fn legend(s: &mut String, scene: &Scene<'_>, x: f64, top: f64) {
    let mut y = top + 2.0;
    let line = 3.0;
    let fs = 1.9;
    let _ = writeln!(s, r#"<g font-size="{fs}">"#);
    let _ = writeln!(
        s,
        r#"<text x="{x:.2}" y="{y:.2}" font-weight="bold">Legend</text>"#
    );
    y += line;
    let _ = writeln!(
        s,
        r##"<rect x="{x:.2}" y="{:.2}" width="4" height="2" fill="#bdbdbd" fill-opacity="0.55" stroke="#8a8a8a" stroke-width="0.1"/><text x="{:.2}" y="{y:.2}">printed by the layer below</text>"##,
        y - 1.6,
        x + 5.0
    );
    // A check picture shows support, not regions.
    let kinds: &[RegionKind] = if scene.samples.is_empty() {
        &[
            RegionKind::Overhang,
            RegionKind::Bridge,
            RegionKind::Floating,
        ]
    } else {
        &[]
    };
    for &kind in kinds {
        y += line;
        let c = region_color(kind);
        let _ = writeln!(
            s,
            r#"<rect x="{x:.2}" y="{:.2}" width="4" height="2" fill="{c}" fill-opacity="0.16" stroke="{c}" stroke-width="0.3" stroke-dasharray="1 0.5"/><text x="{:.2}" y="{y:.2}">{} region (over air)</text>"#,
            y - 1.6,
            x + 5.0,
            kind.name()
        );
    }
    if !scene.samples.is_empty() {
        for (colour, what) in [
            ("#f4a300", "bridged (anchored both ends)"),
            ("#d7191c", "printed in air"),
        ] {
            y += line;
            let _ = writeln!(
                s,
                r#"<circle cx="{:.2}" cy="{:.2}" r="0.7" fill="{colour}"/><text x="{:.2}" y="{y:.2}">{what}</text>"#,
                x + 2.0,
                y - 0.6,
                x + 5.0
            );
        }
    }
    y += line * 0.7;
    for role in roles_present(scene) {
        y += line;
        let _ = writeln!(
            s,
            r#"<line x1="{x:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="{}" stroke-width="0.9" stroke-linecap="round"/><text x="{:.2}" y="{y:.2}">{}</text>"#,
            y - 0.6,
            x + 4.0,
            y - 0.6,
            role_color(role),
            x + 5.0,
            role.name()
        );
    }
    if !scene.poa_blocks.is_empty() {
        y += line;
        let (first, last) = (poa_shade(0, 2), poa_shade(1, 2));
        let _ = writeln!(
            s,
            r#"<line x1="{x:.2}" y1="{a:.2}" x2="{:.2}" y2="{a:.2}" stroke="{first}" stroke-width="0.9" stroke-linecap="round"/><line x1="{:.2}" y1="{a:.2}" x2="{:.2}" y2="{a:.2}" stroke="{last}" stroke-width="0.9" stroke-linecap="round"/><text x="{:.2}" y="{y:.2}">poa loops, first to last</text>"#,
            x + 2.0,
            x + 2.0,
            x + 4.0,
            x + 5.0,
            a = y - 0.6,
        );
    }
    let _ = writeln!(s, "</g>");
}

#[derive(Default)]
struct Bounds {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    n: usize,
}

impl Bounds {
    fn add(&mut self, x: f64, y: f64) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        if self.n == 0 {
            (self.x0, self.y0, self.x1, self.y1) = (x, y, x, y);
        } else {
            self.x0 = self.x0.min(x);
            self.y0 = self.y0.min(y);
            self.x1 = self.x1.max(x);
            self.y1 = self.y1.max(y);
        }
        self.n += 1;
    }

    fn empty(&self) -> bool {
        self.n == 0
    }
}

fn ring_path(ring: &LineString<f64>, tx: &dyn Fn(f64) -> f64, ty: &dyn Fn(f64) -> f64) -> String {
    let mut d = String::new();
    for (i, c) in ring.0.iter().enumerate() {
        let _ = write!(
            d,
            "{}{:.3} {:.3}",
            if i == 0 { "M" } else { " L" },
            tx(c.x),
            ty(c.y)
        );
    }
    d.push_str(" Z");
    d
}

fn polygon_path(p: &Polygon<f64>, tx: &dyn Fn(f64) -> f64, ty: &dyn Fn(f64) -> f64) -> String {
    let mut d = ring_path(p.exterior(), tx, ty);
    for h in p.interiors() {
        d.push(' ');
        d.push_str(&ring_path(h, tx, ty));
    }
    d
}

fn multipolygon_path(
    mp: &MultiPolygon<f64>,
    tx: &dyn Fn(f64) -> f64,
    ty: &dyn Fn(f64) -> f64,
) -> String {
    mp.0.iter()
        .map(|p| polygon_path(p, tx, ty))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Escapes text for XML and HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// One row of the regions index.
pub struct IndexRow {
    pub id: usize,
    pub layer: usize,
    pub z: f64,
    pub kind: RegionKind,
    pub area: f64,
    pub reach: f64,
    pub svg: String,
}

/// The `index.html` of `poa preview --regions`.
pub fn index_html(title: &str, rows: &[IndexRow]) -> String {
    let layers = rows
        .iter()
        .map(|r| r.layer)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>poa: {t}</title>\n<style>body{{font-family:Helvetica,Arial,sans-serif;margin:2em}}table{{border-collapse:collapse}}td,th{{padding:4px 10px;border-bottom:1px solid #ddd;text-align:right}}th{{background:#f4f4f4}}td.k{{text-align:left}}img{{max-width:100%;border:1px solid #ccc;margin:1em 0}}</style></head><body>\n<h1>Regions over air: {t}</h1>\n<p>{} region{} on {} layer{}. Click a row to see its layer.</p>",
        rows.len(),
        if rows.len() == 1 { "" } else { "s" },
        layers,
        if layers == 1 { "" } else { "s" },
        t = escape(title)
    );
    s.push_str("<table><tr><th>#</th><th>layer</th><th>Z mm</th><th>kind</th><th>area mm²</th><th>reach mm</th></tr>\n");
    for r in rows {
        let _ = writeln!(
            s,
            "<tr><td><a href=\"{svg}\">{}</a></td><td>{}</td><td>{:.2}</td><td class=\"k\">{}</td><td>{:.1}</td><td>{:.1}</td></tr>",
            r.id,
            r.layer,
            r.z,
            r.kind.name(),
            r.area,
            r.reach,
            svg = escape(&r.svg)
        );
    }
    s.push_str("</table>\n");
    let mut seen = Vec::new();
    for r in rows {
        if seen.contains(&r.svg) {
            continue;
        }
        seen.push(r.svg.clone());
        let _ = writeln!(
            s,
            "<h2 id=\"layer-{l}\">Layer {l}</h2>\n<img src=\"{svg}\" alt=\"layer {l}\">",
            l = r.layer,
            svg = escape(&r.svg)
        );
    }
    s.push_str("</body></html>\n");
    s
}

/// Pictures of a whole file.
pub struct Previews {
    /// (file name, SVG text) for each layer with regions, in layer order.
    pub layers: Vec<(String, String)>,
    pub index: String,
}

/// Ends the reading of a file once the layer asked for is drawn; told apart from real errors
/// by its type.
#[derive(Debug)]
struct Drawn;

impl std::fmt::Display for Drawn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the layer is drawn")
    }
}

impl std::error::Error for Drawn {}

/// Reads `input` and renders layer `number` (1-based). `None` when the file has no such layer.
pub fn preview_layer<R: BufRead + Send>(
    input: R,
    config: SlicerConfig,
    opts: &DetectOptions,
    number: usize,
    title: &str,
) -> io::Result<Option<String>> {
    let mut svg = None;
    let mut region_id = 0;
    let reader = LayerReader::new(
        input,
        ReaderOptions {
            // The raw lines tell poa's blocks apart (drawn in poa's colour).
            keep_raw: true,
            config,
        },
    );
    // The drawn layer shows the area below even where the proof would not need it.
    let exact = DetectOptions {
        prove: false,
        ..opts.clone()
    };
    let result = geometry::detect(reader, &exact, |d| {
        if d.layer.kind != LayerKind::Layer {
            return Ok(());
        }
        if d.layer.index + 1 == number {
            let numbered: Vec<(usize, &Region)> = d
                .regions
                .iter()
                .enumerate()
                .map(|(i, r)| (region_id + i + 1, r))
                .collect();
            svg = Some(render(&Scene {
                title,
                layer: &d.layer,
                below: d.below.as_ref().unwrap_or(&geometry::NO_AREA),
                regions: &numbered,
                samples: &[],
                poa_blocks: &poa_blocks(&d.layer),
            }));
            // Stop reading once the layer is drawn: the rest of the file does not matter.
            return Err(io::Error::other(Drawn));
        }
        region_id += d.regions.len();
        Ok(())
    });
    match result {
        Err(e) if e.get_ref().is_some_and(|inner| inner.is::<Drawn>()) => Ok(svg),
        Err(e) => Err(e),
        Ok(()) => Ok(svg),
    }
}

/// Reads `input` and renders every layer that has regions, plus an index.
pub fn preview_regions<R: BufRead + Send>(
    input: R,
    config: SlicerConfig,
    opts: &DetectOptions,
    title: &str,
) -> io::Result<Previews> {
    let mut layers = Vec::new();
    let mut rows = Vec::new();
    let reader = LayerReader::new(
        input,
        ReaderOptions {
            // The raw lines tell poa's blocks apart (drawn in poa's colour).
            keep_raw: true,
            config,
        },
    );
    geometry::detect(reader, opts, |d| {
        if d.regions.is_empty() {
            return Ok(());
        }
        let first = rows.len();
        let name = format!("layer-{:04}.svg", d.layer.index + 1);
        let numbered: Vec<(usize, &Region)> = d
            .regions
            .iter()
            .enumerate()
            .map(|(i, r)| (first + i + 1, r))
            .collect();
        let svg = render(&Scene {
            title,
            layer: &d.layer,
            below: d.below.as_ref().unwrap_or(&geometry::NO_AREA),
            regions: &numbered,
            samples: &[],
            poa_blocks: &poa_blocks(&d.layer),
        });
        for (id, r) in &numbered {
            rows.push(IndexRow {
                id: *id,
                layer: d.layer.index + 1,
                z: r.z,
                kind: r.kind,
                area: r.area,
                reach: r.max_distance,
                svg: name.clone(),
            });
        }
        layers.push((name, svg));
        Ok(())
    })?;
    Ok(Previews {
        layers,
        index: index_html(title, &rows),
    })
}

/// Draws layer `number` (1-based) with the deposition check's bridged and in-air samples.
pub fn check_layer_svg<R: BufRead>(
    input: R,
    config: SlicerConfig,
    opts: &crate::check::CheckOptions,
    number: usize,
    title: &str,
) -> io::Result<Option<String>> {
    let fa = config.e_area();
    let reader = LayerReader::new(
        input,
        ReaderOptions {
            // The raw lines tell poa's blocks apart (drawn in poa's colour).
            keep_raw: true,
            config,
        },
    );
    let mut recent: VecDeque<Layer> = VecDeque::new();
    for layer in reader {
        let layer = layer?;
        if layer.kind != LayerKind::Layer {
            continue;
        }
        if layer.index + 1 == number {
            let below = crate::check::resting_on(&layer, recent.iter());
            let c = crate::check::check_layer(&below, &layer, fa, opts, true);
            let area = area_below(&below);
            return Ok(Some(render(&Scene {
                title,
                layer: &layer,
                below: &area,
                regions: &[],
                samples: &c.samples,
                poa_blocks: &poa_blocks(&layer),
            })));
        }
        keep_recent(&mut recent, layer);
    }
    Ok(None)
}

/// At most this many layer pairs go into a compare page (each holds two SVGs).
pub const COMPARE_MAX_LAYERS: usize = 200;

/// One layer of a compare page.
struct ComparedLayer {
    number: usize,
    z: f64,
    in_air: [f64; 2],
    bridged: [f64; 2],
    svg: [String; 2],
}

/// The layers of `input` (not the start and end blocks), with their raw lines.
fn print_layers<R: BufRead>(
    input: R,
    config: SlicerConfig,
) -> impl Iterator<Item = io::Result<Layer>> {
    LayerReader::new(
        input,
        ReaderOptions {
            keep_raw: true,
            config,
        },
    )
    .filter(|l| !matches!(l, Ok(l) if l.kind != LayerKind::Layer))
}

/// Whether two layers print the same strands.
fn same_strands(a: &Layer, b: &Layer) -> bool {
    a.paths.len() == b.paths.len()
        && a.paths
            .iter()
            .zip(&b.paths)
            .all(|(p, q)| p.role == q.role && p.points == q.points && p.seg_e == q.seg_e)
}

/// `poa preview --compare ORIGINAL FILE`: one HTML page with a layer slider showing, side by
/// side, each layer where the two files differ (and the layer above each, which stands on
/// it), with the deposition check's bridged and in-air points marked and poa's loops shaded
/// by order. At most [`COMPARE_MAX_LAYERS`] layers (the page says when more differ).
///
/// Long by design: one lock-step walk over both files that keeps the layer below of each
/// and draws a pair where needed; the drawing is [`render`].
pub fn compare_page<A: BufRead, B: BufRead>(
    original: A,
    original_config: SlicerConfig,
    file: B,
    file_config: SlicerConfig,
    names: [&str; 2],
    opts: &crate::check::CheckOptions,
) -> io::Result<String> {
    let fa = [original_config.e_area(), file_config.e_area()];
    let mut a = print_layers(original, original_config);
    let mut b = print_layers(file, file_config);
    let mut recent: [VecDeque<Layer>; 2] = [VecDeque::new(), VecDeque::new()];
    let mut pages: Vec<ComparedLayer> = Vec::new();
    let (mut differing, mut layers) = (0usize, 0usize);
    let mut above_changed = false;
    while let (Some(la), Some(lb)) = (a.next(), b.next()) {
        let (la, lb) = (la?, lb?);
        layers += 1;
        let changed = !same_strands(&la, &lb);
        differing += changed as usize;
        if (changed || above_changed) && pages.len() < COMPARE_MAX_LAYERS {
            let pair = [&la, &lb];
            let mut in_air = [0.0; 2];
            let mut bridged = [0.0; 2];
            let mut svg = [String::new(), String::new()];
            for i in 0..2 {
                let below = crate::check::resting_on(pair[i], recent[i].iter());
                let c = crate::check::check_layer(&below, pair[i], fa[i], opts, true);
                in_air[i] = c.in_air_mm;
                bridged[i] = c.bridged_mm;
                let area = area_below(&below);
                svg[i] = render(&Scene {
                    title: names[i],
                    layer: pair[i],
                    below: &area,
                    regions: &[],
                    samples: &c.samples,
                    poa_blocks: &poa_blocks(pair[i]),
                });
            }
            pages.push(ComparedLayer {
                number: la.index + 1,
                z: la.z,
                in_air,
                bridged,
                svg,
            });
        }
        above_changed = changed;
        keep_recent(&mut recent[0], la);
        keep_recent(&mut recent[1], lb);
    }
    Ok(compare_html(names, &pages, differing, layers))
}

/// Layers kept for what the next layers rest on: a few, enough for objects of different
/// layer heights interleaving.
const KEEP_RECENT: usize = 8;

fn keep_recent(recent: &mut VecDeque<Layer>, layer: Layer) {
    if recent.len() == KEEP_RECENT {
        recent.pop_front();
    }
    recent.push_back(layer);
}

/// The printed area of the layers below, drawn under a layer.
fn area_below(below: &[&Layer]) -> MultiPolygon<f64> {
    below.iter().fold(MultiPolygon::new(Vec::new()), |acc, l| {
        geometry::union(
            &acc,
            &geometry::printed_area(l, &geometry::AreaOptions::default()),
        )
    })
}

fn compare_html(
    names: [&str; 2],
    pages: &[ComparedLayer],
    differing: usize,
    layers: usize,
) -> String {
    let mut s = String::new();
    let (a, b) = (escape(names[0]), escape(names[1]));
    let _ = writeln!(
        s,
        r#"<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>poa compare: {a} / {b}</title>
<style>
body {{ font-family: Helvetica, Arial, sans-serif; margin: 1em; }}
.controls {{ position: sticky; top: 0; background: white; padding: .4em 0; }}
.controls input {{ width: 50%; vertical-align: middle; }}
.pair {{ display: flex; gap: 1em; }}
.pair[hidden] {{ display: none; }}
figure {{ flex: 1; margin: 0; }}
figure svg {{ width: 100%; height: auto; border: 1px solid #ddd; }}
.worse {{ color: #d7191c; font-weight: bold; }}
</style></head><body>
<h1>{a} (left) and {b} (right)</h1>"#
    );
    let more = if pages.len() < differing {
        format!(" (the first {} are shown)", pages.len())
    } else {
        String::new()
    };
    let _ = writeln!(
        s,
        "<p id=\"summary\">{differing} of {layers} layers differ{more}; each is shown with the layer above it. Marked points are the deposition check's: amber bridged, red in air. poa's loops are purple, lighter the later they print.</p>"
    );
    if pages.is_empty() {
        s.push_str("<p>The two files print the same strands on every layer.</p>\n");
    }
    let _ = writeln!(
        s,
        r#"<div class="controls"><button id="prev" type="button">&#9664;</button> <input id="layer" type="range" min="0" max="{}" value="0" aria-label="layer"> <button id="next" type="button">&#9654;</button> <span id="label"></span></div>"#,
        pages.len().saturating_sub(1)
    );
    for p in pages {
        let worse = p.in_air[1] > p.in_air[0] + 0.5;
        let _ = writeln!(
            s,
            r#"<div class="pair" data-layer="{n}" data-z="{z:.3}" data-in-air="{a0:.1} {a1:.1}" hidden>
<figure><figcaption>{a}: layer {n} at Z {z:.2}: {a0:.1} mm in air, {b0:.1} mm bridged</figcaption>
{s0}</figure>
<figure><figcaption{cls}>{b}: layer {n} at Z {z:.2}: {a1:.1} mm in air, {b1:.1} mm bridged</figcaption>
{s1}</figure></div>"#,
            n = p.number,
            z = p.z,
            a0 = p.in_air[0],
            a1 = p.in_air[1],
            b0 = p.bridged[0],
            b1 = p.bridged[1],
            s0 = p.svg[0],
            s1 = p.svg[1],
            cls = if worse { r#" class="worse""# } else { "" },
        );
    }
    s.push_str(
        r#"<script>
(function () {
  var pairs = Array.prototype.slice.call(document.querySelectorAll('.pair'));
  var slider = document.getElementById('layer');
  var label = document.getElementById('label');
  function show(k) {
    if (!pairs.length) { return; }
    k = Math.max(0, Math.min(pairs.length - 1, k));
    slider.value = k;
    pairs.forEach(function (p, i) { p.hidden = i !== k; });
    var p = pairs[k];
    var air = p.dataset.inAir.split(' ');
    label.textContent = 'layer ' + p.dataset.layer + ' at Z ' + p.dataset.z + ' mm: in air ' + air[0] + ' -> ' + air[1] + ' mm';
    document.body.dataset.shown = p.dataset.layer;
  }
  slider.addEventListener('input', function () { show(+slider.value); });
  document.getElementById('prev').addEventListener('click', function () { show(+slider.value - 1); });
  document.getElementById('next').addEventListener('click', function () { show(+slider.value + 1); });
  document.addEventListener('keydown', function (e) {
    if (e.key === 'ArrowLeft') { show(+slider.value - 1); }
    if (e.key === 'ArrowRight') { show(+slider.value + 1); }
  });
  var want = new URLSearchParams(location.search).get('layer');
  var start = pairs.findIndex(function (p) { return p.dataset.layer === want; });
  show(start < 0 ? 0 : start);
  document.body.dataset.ready = '1';
})();
</script>
</body></html>
"#,
    );
    s
}
