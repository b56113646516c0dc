//! The Print-on-Air rewrite on the specimens, checked by simulating the deposition.

use crate::common;

use common::*;
use geo::{Area, MultiPolygon};
use printonair::check::{check_layer, CheckOptions, Support};
use printonair::emit;
use printonair::geometry::{self, difference, footprint, offset, printed_area, AreaOptions};
use printonair::layers::{Layer, LayerKind, SlicerConfig};
use printonair::poa::BridgeMode;
use printonair::report;

fn point_in(area: &MultiPolygon<f64>, p: [f64; 2]) -> bool {
    use geo::Contains;
    area.contains(&geo::Point::new(p[0], p[1]))
}

fn footprint_by_e(layer: &Layer, fa: f64) -> MultiPolygon<f64> {
    let paths: Vec<_> = layer
        .paths
        .iter()
        .map(|p| {
            let mut q = p.clone();
            q.width = p.e_width(fa);
            q
        })
        .collect();
    footprint(paths.iter())
}

fn check_specimen(name: &str, suffix: &str) {
    let original = read(&sample(&format!("{name}_prusa_{suffix}.gcode")));
    let bridges = if name == "bridge" {
        BridgeMode::Poa
    } else {
        BridgeMode::Keep
    };
    let (out, rep) = rewrite(&original, bridges);
    let what = format!("{name} {suffix}");
    assert_eq!(rep.regions_rewritten, 1, "{what}: {rep:?}");
    let blocks = poa_blocks(&out);
    assert_eq!(blocks.len(), 1, "{what}");

    let before = all_layers(&original);
    let after = all_layers(&out);
    assert_eq!(layer_count(&before), layer_count(&after), "{what}");
    let fa = SlicerConfig::parse(&original).filament_diameter();
    let fa = printonair::layers::filament_area(fa);

    // Which layer was rewritten.
    let (ai, layer) = after
        .iter()
        .enumerate()
        .find(|(_, l)| {
            l.kind == LayerKind::Layer && l.first_line <= blocks[0].0 && blocks[0].1 <= l.last_line
        })
        .expect("block inside a layer");
    assert!(
        (layer.z - 10.2).abs() < 1e-6,
        "{what}: rewritten layer at {}",
        layer.z
    );
    let below = &after[ai - 1];

    // Every strand poa wrote rests on material deposited before it.
    let opts = CheckOptions::default();
    let c = check_layer(&[below], layer, fa, &opts, true);
    let poa_samples: Vec<_> = c
        .samples
        .iter()
        .filter(|s| blocks.iter().any(|(a, b)| s.line >= *a && s.line <= *b))
        .collect();
    assert!(
        poa_samples.len() > 1000,
        "{what}: {} samples",
        poa_samples.len()
    );
    let bad: Vec<_> = poa_samples
        .iter()
        .filter(|s| s.support != Support::Supported)
        .collect();
    assert!(
        bad.is_empty(),
        "{what}: {} of poa's samples unsupported, first at {:?} line {}",
        bad.len(),
        bad[0].point,
        bad[0].line
    );
    // The layer as a whole.
    let held = (c.supported_mm + c.bridged_mm) / c.length_mm;
    assert!(held >= 0.99, "{what}: {held} supported or bridged, {c:?}");
    assert!(
        c.density >= 0.9 && c.density <= 1.6,
        "{what}: density {}",
        c.density
    );

    // Coverage of the region, and nothing outside the original outline.
    let orig_layer = before
        .iter()
        .find(|l| l.kind == LayerKind::Layer && (l.z - layer.z).abs() < 1e-9)
        .unwrap();
    let orig_below = before
        .iter()
        .find(|l| l.kind == LayerKind::Layer && l.index + 1 == orig_layer.index)
        .unwrap();
    let area_opts = AreaOptions::default();
    let sect_a = printed_area(orig_below, &area_opts);
    let sect_b = printed_area(orig_layer, &area_opts);
    let cfg = SlicerConfig::parse(&original);
    let regions =
        geometry::find_regions(&sect_a, orig_layer, &sect_b, &report::detect_options(&cfg));
    assert_eq!(regions.len(), 1);
    let region = MultiPolygon::new(vec![regions[0].polygon.clone()]);
    // In air: nothing in or near the region. The slicer's own strands elsewhere on this layer
    // (sparse infill ends over the sparse infill below) are left as they were, so they are
    // measured on the original and allowed, on top of the 1 mm budget.
    let near = offset(&region, 2.0);
    let in_air_near = |c: &printonair::check::LayerCheck| -> f64 {
        c.samples
            .iter()
            .filter(|s| s.support == Support::InAir && point_in(&near, s.point))
            .map(|s| s.length)
            .sum()
    };
    assert!(
        in_air_near(&c) < 1e-9,
        "{what}: {} mm in air near the region",
        in_air_near(&c)
    );
    let orig_check = check_layer(&[orig_below], orig_layer, fa, &opts, true);
    let orig_elsewhere: f64 = orig_check
        .samples
        .iter()
        .filter(|s| s.support == Support::InAir && !point_in(&near, s.point))
        .map(|s| s.length)
        .sum();
    assert!(
        c.in_air_mm <= 1.0 + orig_elsewhere + 1e-9,
        "{what}: {} mm in air (the slicer left {} mm elsewhere) at {:?}",
        c.in_air_mm,
        orig_elsewhere,
        c.longest_in_air_at
    );
    let fp = footprint_by_e(layer, fa);
    let uncovered = difference(&region, &fp).unsigned_area();
    assert!(
        uncovered < 0.02 * regions[0].area,
        "{what}: {uncovered} mm2 of {} uncovered",
        regions[0].area
    );
    let outside = difference(&fp, &offset(&sect_b, 0.1)).unsigned_area();
    assert!(outside < 0.05, "{what}: {outside} mm2 outside the outline");

    // Other layers byte for byte; the rewritten layer keeps every line it did not split.
    // The statistics footer (in the last layer) is updated for what poa added.
    let stats = |l: &[u8]| -> bool {
        [
            &b"; filament used"[..],
            b"; total filament",
            b"; filament cost",
            b"; estimated printing time",
        ]
        .iter()
        .any(|p| l.starts_with(p))
    };
    let without_stats = |raw: &[u8]| -> Vec<u8> {
        raw.split(|&c| c == b'\n')
            .filter(|l| !stats(l))
            .flat_map(|l| l.iter().copied().chain([b'\n']))
            .collect()
    };
    let used = |d: &[u8]| -> f64 {
        String::from_utf8_lossy(d)
            .lines()
            .find_map(|l| l.strip_prefix("; filament used [mm] = "))
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!(
        (used(&out) - used(&original) - rep.filament_added_mm).abs() < 0.01,
        "{what}: footer"
    );
    for (b, a) in before.iter().zip(&after) {
        if a.first_line == layer.first_line || b.kind == LayerKind::Preamble {
            continue;
        }
        assert!(
            without_stats(&a.raw) == without_stats(&b.raw),
            "{what}: layer {} changed",
            b.index + 1
        );
    }
    let split: Vec<&[u8]> = layer
        .raw
        .split(|&c| c == b'\n')
        .filter_map(|l| l.strip_prefix(b"; poa: split "))
        .collect();
    let mut out_lines = layer.raw.split(|&c| c == b'\n');
    for line in orig_layer.raw.split(|&c| c == b'\n') {
        if split.iter().any(|s| *s == line.trim_ascii()) {
            continue;
        }
        assert!(
            out_lines.any(|l| l == line),
            "{what}: kept line {:?} missing",
            String::from_utf8_lossy(line)
        );
    }
}

#[test]
fn rect_overhang_relative_and_absolute() {
    check_specimen("rect_overhang", "rel");
    check_specimen("rect_overhang", "abs");
}

#[test]
fn circ_overhang_relative_and_absolute() {
    check_specimen("circ_overhang", "rel");
    check_specimen("circ_overhang", "abs");
}

#[test]
fn tri_overhang_relative_and_absolute() {
    check_specimen("tri_overhang", "rel");
    check_specimen("tri_overhang", "abs");
}

#[test]
fn bridge_with_bridges_poa_relative_and_absolute() {
    check_specimen("bridge", "rel");
    check_specimen("bridge", "abs");
}

#[test]
fn bridges_are_kept_by_default() {
    let original = read(&sample("bridge_prusa_rel.gcode"));
    let (out, rep) = rewrite(&original, BridgeMode::Keep);
    assert_eq!(rep.regions_rewritten, 0);
    assert_eq!(rep.skipped.len(), 1);
    assert!(poa_blocks(&out).is_empty());
}

#[test]
fn filament_bookkeeping_is_exact_in_both_e_modes() {
    for suffix in ["rel", "abs"] {
        let original = read(&sample(&format!("rect_overhang_prusa_{suffix}.gcode")));
        let (out, rep) = rewrite(&original, BridgeMode::Keep);
        let total = |d: &[u8]| -> f64 {
            all_layers(d)
                .iter()
                .flat_map(|l| &l.paths)
                .map(|p| p.e())
                .sum()
        };
        let (a, b) = (total(&original), total(&out));
        let s = &rep.rewrites[0];
        let expected = a - s.removed_filament_mm + s.written_filament_mm;
        assert!((b - expected).abs() < 1e-3, "{suffix}: {b} vs {expected}");
    }
}

#[test]
fn running_twice_changes_nothing() {
    let original = read(&sample("rect_overhang_prusa_rel.gcode"));
    let (out, _) = rewrite(&original, BridgeMode::Keep);
    assert!(emit::already_processed(&out[..out.len().min(65536)]));
    assert!(!emit::already_processed(&original[..65536]));
}

/// OrcaSlicer's files, for Bambu printers (`; FEATURE:` tags) and for others (`;TYPE:Outer
/// wall`), are rewritten exactly as their PrusaSlicer twin (the same moves, told in PrusaSlicer's
/// tags): the same regions, loops and bytes, and poa's own tags in the file's dialect (an
/// Orca viewer shows no `;TYPE:` of a Bambu file and no role named "Overhang perimeter");
/// Bambu's auxiliary fan (`M106 P2`) is not taken for the part fan that poa restores.
#[test]
fn orca_and_bambu_files_are_rewritten_as_their_prusaslicer_twin_in_their_own_tags() {
    let mut files: Vec<(String, Vec<u8>)> = samples()
        .iter()
        .filter(|p| p.to_string_lossy().contains("_prusa_"))
        .map(|p| (p.display().to_string(), read(p)))
        .collect();
    assert!(files.len() >= 8);
    // Gradual overhangs' blocks tag their beads' widths too.
    for part in ["hook", "sphere_stem"] {
        if let Some(d) = slice(part, &[]) {
            files.push((format!("{part} by PrusaSlicer"), d));
        }
    }
    // Bambu's auxiliary fan lines follow the part fan's, poa's own included when the
    // PrusaSlicer file's rewrite is retold: compared without them.
    let without_mark = |d: &[u8]| -> Vec<u8> {
        d.split_inclusive(|&b| b == b'\n')
            .filter(|l| !l.starts_with(emit::HEADER_MARK.as_bytes()))
            .filter(|l| l.trim_ascii() != BAMBU_AUX_FAN.as_bytes())
            .flatten()
            .copied()
            .collect()
    };
    for (name, prusa) in &files {
        let (out, rep) = rewrite(prusa, BridgeMode::Auto);
        assert!(rep.regions_rewritten >= 1, "{name}: nothing rewritten");
        for bambu in [false, true] {
            let what = format!("{name} as OrcaSlicer writes it (Bambu tags: {bambu})");
            let (orca_out, orca_rep) = rewrite(&as_orca(prusa, bambu), BridgeMode::Auto);
            assert_eq!(
                (orca_rep.regions_rewritten, orca_rep.rewrites.len()),
                (rep.regions_rewritten, rep.rewrites.len()),
                "{what}"
            );
            assert!(
                without_mark(&orca_out) == without_mark(&as_orca(&out, bambu)),
                "{what}: not the PrusaSlicer file's rewrite, retold"
            );
            let text = String::from_utf8_lossy(&orca_out);
            assert!(!text.contains("Overhang perimeter"), "{what}");
            if bambu {
                assert!(
                    !text
                        .lines()
                        .any(|l| l.starts_with(";TYPE:") || l.starts_with(";WIDTH:")),
                    "{what}: PrusaSlicer's tags in a Bambu file"
                );
            }
        }
    }
}

/// Other dialects: poa's strands rest on material and the file's E count stays right.
#[test]
fn cura_slic3r_and_comment_less_files() {
    for name in [
        "rect_overhang_cura.gcode",
        "rect_overhang_slic3r.gcode",
        "rect_overhang_nocomments.gcode",
    ] {
        let original = read(&sample(name));
        let (out, rep) = rewrite(&original, BridgeMode::Keep);
        assert_eq!(rep.regions_rewritten, 1, "{name}");
        let blocks = poa_blocks(&out);
        let after = all_layers(&out);
        let fa =
            printonair::layers::filament_area(SlicerConfig::parse(&original).filament_diameter());
        let i = after
            .iter()
            .position(|l| l.first_line <= blocks[0].0 && blocks[0].1 <= l.last_line)
            .unwrap();
        let c = check_layer(
            &[&after[i - 1]],
            &after[i],
            fa,
            &CheckOptions::default(),
            true,
        );
        let bad = c
            .samples
            .iter()
            .filter(|s| s.line >= blocks[0].0 && s.line <= blocks[0].1)
            .filter(|s| s.support != Support::Supported)
            .count();
        assert_eq!(bad, 0, "{name}: poa strands unsupported");
        let total = |d: &[u8]| -> f64 {
            all_layers(d)
                .iter()
                .flat_map(|l| &l.paths)
                .map(|p| p.e())
                .sum()
        };
        let s = &rep.rewrites[0];
        let expected = total(&original) - s.removed_filament_mm + s.written_filament_mm;
        assert!(
            (total(&out) - expected).abs() < 1e-3,
            "{name}: E bookkeeping"
        );
    }
}

#[test]
fn a_file_written_without_blanks_is_rewritten_as_the_same_file_with_them() {
    // `G1X60E9F1000` (as MeatPack sends lines, or a file squeezed to save bytes) is X 60,
    // E 9 to every firmware; read as X 60e9 it made twelve false floating regions and lost
    // the real one.
    let spaced = read(&sample("rect_overhang_prusa_abs.gcode"));
    let packed: Vec<u8> = spaced
        .split_inclusive(|&b| b == b'\n')
        .flat_map(|line| {
            let cut = line.iter().position(|&b| b == b';').unwrap_or(line.len());
            let (code, comment) = line.split_at(cut);
            code.iter()
                .copied()
                .filter(|&b| b != b' ')
                .chain(comment.iter().copied())
                .collect::<Vec<u8>>()
        })
        .collect();
    assert!(packed.len() < spaced.len() - 50_000);
    let (out_s, rep_s) = rewrite(&spaced, BridgeMode::Keep);
    let (out_p, rep_p) = rewrite(&packed, BridgeMode::Keep);
    assert_eq!(rep_s.regions_rewritten, 1);
    assert_eq!(rep_p.regions_rewritten, rep_s.regions_rewritten);
    let block = |out: &[u8]| -> Vec<u8> {
        let (a, b) = poa_blocks(out)[0];
        out.split(|&c| c == b'\n')
            .skip(a as usize - 1)
            .take((b - a + 1) as usize)
            .flat_map(|l| l.iter().copied().chain(std::iter::once(b'\n')))
            .collect()
    };
    assert_eq!(block(&out_p), block(&out_s), "the loops differ");
}

/// What `poa process` made of `file` before the output was assembled: the rewrite streamed
/// into memory, then its progress lines updated over the whole text.
fn streamed(file: &std::path::Path) -> Vec<u8> {
    use printonair::rewrite::Request;
    use printonair::{input, progress};
    let opened = input::open(file).unwrap();
    let req = Request::default();
    let opts = req.options(&opened.config).unwrap();
    let totals = progress::Totals::of(&opened.config);
    let mut text = Vec::new();
    let rep = emit::process(
        opened.reader,
        opened.config,
        &opts,
        &mut emit::Plain(&mut text),
    )
    .unwrap();
    if rep.has_progress_lines && !rep.progress.is_empty() {
        let mut fixed = Vec::new();
        progress::update(&text[..], &mut fixed, &rep.progress, totals).unwrap();
        text = fixed;
    }
    text
}

fn written(file: &std::path::Path, dir: &std::path::Path) -> Vec<u8> {
    let out = dir.join("out.gcode");
    let req = printonair::rewrite::Request::default();
    printonair::rewrite::rewrite_file(file, Some(&out), &[file], &req, &|r, _| r)
        .unwrap()
        .expect("not rewritten before");
    std::fs::read(&out).unwrap()
}

/// A rewrite into a regular file is assembled from the input's stretches and the made text
/// and written once (`printonair::assemble`): byte for byte what streaming it and updating
/// its progress lines afterwards makes, on every sample (progress lines that change and
/// change length, CRLF, no comments, several objects).
#[test]
fn a_rewrite_written_once_is_the_streamed_rewrite_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut with_progress = 0;
    for s in samples() {
        let got = written(&s, dir.path());
        let expect = streamed(&s);
        assert!(got == expect, "{}: outputs differ", s.display());
        if got != read(&s) && memchr::memmem::find(&got, b"\nM73 P").is_some() {
            with_progress += 1;
        }
    }
    assert!(
        with_progress >= 3,
        "samples with progress lines: {with_progress}"
    );
}

/// A file with more progress lines than the assembler lists is written the streaming way,
/// with the same result.
#[test]
fn a_file_of_countless_progress_lines_is_streamed_instead() {
    let original = read(&sample("rect_overhang_prusa_rel.gcode"));
    let at = memchr::memmem::find(&original, b"\nM73 P").expect("progress lines") + 1;
    let mut data = original[..at].to_vec();
    for _ in 0..printonair::assemble::MAX_ENTRIES + 10 {
        data.extend_from_slice(b"M73 P0 R9\n");
    }
    data.extend_from_slice(&original[at..]);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("many.gcode");
    std::fs::write(&file, &data).unwrap();
    let got = written(&file, dir.path());
    assert!(got == streamed(&file), "outputs differ");
    // The added time reached the lines.
    assert!(memchr::memmem::find(&got, b"\nM73 P0 R10\n").is_some());
}
