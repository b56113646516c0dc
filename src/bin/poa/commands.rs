//! The commands with more to do than one library call: `process` (many files, a table),
//! `check` (compare, draw, fail) and `preview` (one layer or a folder).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use printonair::emit::ProcessReport;
use printonair::rewrite::{self, Request};
use printonair::{input, output, preview, report};

use crate::args::{
    CheckArgs, DeformArgs, DetectArgs, FiveAxisArgs, RewriteArgs, SweepArgs, TextureArgs,
};
use crate::print::{
    emit, emit_json, error_text, skipped_line, summary_line, verbose_lines, write_stdout,
};

/// Writes an output file atomically, refusing to write over any of `inputs`.
fn write_file(path: &Path, inputs: &[&Path], text: &str) -> anyhow::Result<()> {
    output::write_bytes(path, inputs, text.as_bytes())?;
    Ok(())
}

/// `poa check`.
pub fn check(args: CheckArgs) -> anyhow::Result<ExitCode> {
    let CheckArgs {
        file,
        json,
        overlap_min,
        max_bridge,
        fail_in_air,
        compare,
        svg_layer,
        output: svg_out,
        machine,
        width,
        layer_height,
    } = args;
    if let Some(m) = machine {
        return check_joints(&file, &m, width, layer_height, json, fail_in_air);
    }
    anyhow::ensure!(
        (0.0..0.5).contains(&overlap_min),
        "--overlap-min must be between 0 and 0.5"
    );
    anyhow::ensure!(max_bridge >= 0.0, "--max-bridge must be 0 or more");
    if let Some(out) = &svg_out {
        let mut inputs = vec![file.as_path()];
        inputs.extend(compare.as_deref());
        output::check_not_input(out, &inputs)?;
    }
    let opened = input::open(&file)?;
    if opened.binary.is_none() && compare.is_none() && svg_layer.is_none() {
        if let Some(code) = check_layerless(&file, opened.config.clone(), json, fail_in_air)? {
            return Ok(code);
        }
    }
    let opts = printonair::check::CheckOptions {
        overlap_min,
        max_bridge,
        ..Default::default()
    };
    let name = file.display().to_string();
    let rep = report::check(opened.reader, opened.config, &opts, &name).map_err(|source| {
        printonair::Error::Read {
            path: file.clone(),
            source,
        }
    })?;
    let in_air = rep.in_air_mm;
    if let (Some(n), Some(out)) = (svg_layer, svg_out) {
        let again = input::open(&file)?;
        let title = file
            .file_name()
            .map(|f| f.to_string_lossy().to_string())
            .unwrap_or_default();
        let svg = preview::check_layer_svg(again.reader, again.config, &opts, n, &title).map_err(
            |source| printonair::Error::Read {
                path: file.clone(),
                source,
            },
        )?;
        let Some(svg) = svg else {
            anyhow::bail!("{} has no layer {n}", file.display());
        };
        let mut inputs = vec![file.as_path()];
        inputs.extend(compare.as_deref());
        write_file(&out, &inputs, &svg)?;
    }
    if let Some(orig) = compare {
        let o = input::open(&orig)?;
        let orig_name = orig.display().to_string();
        let before = report::check(o.reader, o.config, &opts, &orig_name)
            .map_err(|source| printonair::Error::Read { path: orig, source })?;
        emit(&report::compare(before, rep), json)?;
    } else {
        emit(&rep, json)?;
    }
    if let Some(limit) = fail_in_air.filter(|limit| in_air > *limit) {
        eprintln!(
            "poa: {} prints {in_air:.1} mm in air, more than --fail-in-air {limit} mm",
            file.display()
        );
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}

/// `poa preview`.
pub fn preview(
    file: PathBuf,
    layer: Option<usize>,
    regions: bool,
    output: PathBuf,
    detect: DetectArgs,
) -> anyhow::Result<ExitCode> {
    if regions {
        check_regions_folder(&output, &file)?;
    } else {
        output::check_not_input(&output, &[&file])?;
    }
    let opened = input::open(&file)?;
    let opts = detect.options(&opened.config)?;
    let title = file
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let read_err = |source| printonair::Error::Read {
        path: file.clone(),
        source,
    };
    if opened.binary.is_none() {
        let src = printonair::helix::FileSource(&file);
        if let Some(p) = printonair::helix::picture::layerless_in(&src, &opened.config, &title)? {
            return preview_layerless(&file, &output, &p);
        }
    }
    anyhow::ensure!(
        regions || layer.is_some(),
        "say what to draw: --layer N -o FILE.svg (one layer) or --regions -o DIR (every layer with regions)"
    );
    if regions {
        let previews = preview::preview_regions(opened.reader, opened.config, &opts, &title)
            .map_err(read_err)?;
        std::fs::create_dir_all(&output).map_err(|source| printonair::Error::Write {
            path: output.clone(),
            source,
        })?;
        for (name, svg) in &previews.layers {
            write_file(&output.join(name), &[&file], svg)?;
        }
        write_file(&output.join("index.html"), &[&file], &previews.index)?;
        eprintln!(
            "poa: {} layer{} with regions drawn; open {}",
            previews.layers.len(),
            if previews.layers.len() == 1 { "" } else { "s" },
            output.join("index.html").display()
        );
    } else if let Some(n) = layer {
        let svg = preview::preview_layer(opened.reader, opened.config, &opts, n, &title)
            .map_err(read_err)?;
        let Some(svg) = svg else {
            anyhow::bail!(
                "{} has no layer {n}; `poa info` shows how many it has",
                file.display()
            );
        };
        write_file(&output, &[&file], &svg)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// One file's rewrite with the CLI's extras: a progress bar for one big file, `-v` lines.
pub fn rewrite_one(
    file: &Path,
    dest: Option<&Path>,
    inputs: &[&Path],
    args: &RewriteArgs,
    req: &Request,
    bar: bool,
) -> anyhow::Result<Option<ProcessReport>> {
    let wrap =
        move |r: Box<dyn std::io::BufRead + Send>, size: u64| -> Box<dyn std::io::BufRead + Send> {
            Box::new(crate::print::Progress::new(r, size, bar))
        };
    if let (Some(dest), true) = (dest, dest != Some(file)) {
        let binary = std::fs::File::open(file).ok().and_then(|mut f| {
            let mut magic = [0u8; 4];
            std::io::Read::read_exact(&mut f, &mut magic).ok()?;
            Some(printonair::bgcode::is_bgcode(&magic))
        });
        if binary == Some(true) && dest.extension().is_none_or(|e| e != "bgcode") {
            eprintln!(
                "poa: note: {} is binary G-code, so {} is written as binary G-code too (PrusaSlicer names such files .bgcode; `poa convert` makes text)",
                file.display(),
                dest.display()
            );
        }
    }
    let report = rewrite::rewrite_file(file, dest, inputs, req, &wrap)?;
    if let (Some(r), true) = (&report, args.verbose) {
        write_stdout(&verbose_lines(r))?;
    }
    Ok(report)
}

pub fn process(
    files: &[PathBuf],
    output: Option<PathBuf>,
    out_dir: Option<PathBuf>,
    dry_run: bool,
    report_path: Option<PathBuf>,
    args: &RewriteArgs,
) -> anyhow::Result<ExitCode> {
    let req = args.request()?;
    if files.len() > 1 && out_dir.is_none() && !dry_run {
        anyhow::bail!("several inputs need --out-dir DIR (or --dry-run)");
    }
    if output.is_none() && out_dir.is_none() && !dry_run {
        anyhow::bail!("say where to write: -o OUT, --out-dir DIR, or --dry-run");
    }
    let dest_of = |file: &PathBuf| -> Option<PathBuf> {
        if dry_run {
            None
        } else if let Some(o) = &output {
            Some(o.clone())
        } else {
            out_dir
                .as_ref()
                .map(|d| d.join(file.file_name().unwrap_or_default()))
        }
    };
    // Everything that could overwrite an input, or two results landing in one file, is
    // refused before any work.
    let inputs: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
    let mut taken: std::collections::HashMap<PathBuf, &PathBuf> = Default::default();
    for file in files {
        let Some(d) = dest_of(file) else { continue };
        if output::same_file(file, &d) {
            anyhow::bail!(
                "{} is the input {} itself; use slicer mode (poa FILE) to rewrite in place",
                d.display(),
                file.display()
            );
        }
        output::check_not_input(&d, &inputs)?;
        if let Some(other) = taken.insert(d.clone(), file) {
            anyhow::bail!(
                "{} and {} would both be written to {}; process them in separate runs or rename one",
                other.display(),
                file.display(),
                d.display()
            );
        }
    }
    if let Some(p) = &report_path {
        output::check_not_input(p, &inputs)?;
        anyhow::ensure!(
            !taken.keys().any(|d| d == p || output::same_file(d, p)),
            "--report {} is also a G-code output; give the report its own name",
            p.display()
        );
    }
    if let Some(dir) = out_dir.as_ref() {
        if !dry_run {
            std::fs::create_dir_all(dir).map_err(|source| printonair::Error::Write {
                path: dir.clone(),
                source,
            })?;
        }
    }
    // Every file is tried, on all cores; one bad file does not stop the others.
    let outcomes: Vec<(PathBuf, Result<Option<ProcessReport>, String>)> = {
        use rayon::prelude::*;
        files
            .par_iter()
            .map(|file| {
                let dest = dest_of(file);
                let result = (|| -> anyhow::Result<Option<ProcessReport>> {
                    let r =
                        rewrite_one(file, dest.as_deref(), &inputs, args, &req, files.len() == 1)?;
                    if r.is_none() {
                        if let Some(d) = &dest {
                            rewrite::copy_file(file, d, &inputs)?;
                        }
                    }
                    Ok(r)
                })();
                (file.clone(), result.map_err(|e| error_text(&e)))
            })
            .collect()
    };
    let mut reports = Vec::new();
    let mut failed = 0;
    let mut text = String::new();
    if files.len() > 1 {
        text.push_str(&format!(
            "{:<40} {:<12} {:>7} {:>9} {:>6} {:>8} {:>11}  status\n",
            "file", "slicer", "regions", "rewritten", "loops", "time s", "filament mm"
        ));
    }
    for (file, result) in &outcomes {
        match result {
            Ok(Some(r)) if files.len() > 1 => {
                text.push_str(&format!(
                    "{:<40} {:<12} {:>7} {:>9} {:>6} {:>+8.0} {:>+11.1}  {}\n",
                    file.display(),
                    r.slicer,
                    r.regions_found,
                    r.regions_rewritten,
                    r.loops,
                    r.time_added_s,
                    r.filament_added_mm,
                    if dry_run { "dry run" } else { "ok" }
                ));
            }
            Ok(r) => {
                text.push_str(&summary_line(file, r.as_ref(), dry_run));
                if let (Some(r), false) = (r, args.verbose) {
                    const SHOWN: usize = 20;
                    for s in r.skipped.iter().take(SHOWN) {
                        text.push_str(&format!("  {}\n", skipped_line(s)));
                    }
                    if r.skipped.len() > SHOWN {
                        text.push_str(&format!(
                            "  ... and {} more regions left as sliced (-v lists them all)\n",
                            r.skipped.len() - SHOWN
                        ));
                    }
                }
            }
            Err(e) => {
                failed += 1;
                if files.len() > 1 {
                    text.push_str(&format!("{:<40} {e}\n", file.display()));
                } else {
                    eprintln!("poa: {e}");
                }
            }
        }
        match result {
            Ok(Some(r)) => reports.push(serde_json::json!({"file": file, "report": r})),
            Ok(None) => reports.push(serde_json::json!({"file": file, "already_processed": true})),
            Err(e) => reports.push(serde_json::json!({"file": file, "error": e})),
        }
    }
    write_stdout(&text)?;
    if let Some(p) = report_path {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "files": reports }))?;
        write_file(&p, &inputs, &text)?;
    }
    if failed > 0 && files.len() > 1 {
        // The table on stdout says which; stderr says that the run failed and what to do.
        eprintln!(
            "poa: {failed} of {} files failed (marked in the table above); the others were written to {}",
            files.len(),
            out_dir
                .as_ref()
                .map_or_else(|| "nowhere (dry run)".to_string(), |d| d.display().to_string())
        );
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// `poa preview --compare ORIGINAL FILE -o DIR`: the side-by-side page in `DIR/index.html`.
pub fn preview_compare(original: &Path, file: &Path, output: &Path) -> anyhow::Result<ExitCode> {
    check_regions_folder(output, file)?;
    output::check_not_input(output, &[original])?;
    let a = input::open(original)?;
    let b = input::open(file)?;
    let name = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default()
    };
    let (na, nb) = (name(original), name(file));
    let page = preview::compare_page(
        a.reader,
        a.config,
        b.reader,
        b.config,
        [&na, &nb],
        &printonair::check::CheckOptions::default(),
    )
    .map_err(|source| printonair::Error::Read {
        path: file.to_path_buf(),
        source,
    })?;
    std::fs::create_dir_all(output).map_err(|source| printonair::Error::Write {
        path: output.to_path_buf(),
        source,
    })?;
    let index = output.join("index.html");
    write_file(&index, &[original, file], &page)?;
    eprintln!("poa: open {}", index.display());
    Ok(ExitCode::SUCCESS)
}

/// `poa preview` of a layer-less (helical) print: the side profile as `-o FILE.svg`, or a
/// folder with the HTML page and both pictures.
fn preview_layerless(
    file: &Path,
    output: &Path,
    p: &printonair::helix::picture::Pictures,
) -> anyhow::Result<ExitCode> {
    if output.extension().is_some_and(|e| e == "svg") {
        write_file(output, &[file], &p.profile)?;
    } else {
        check_regions_folder(output, file)?;
        std::fs::create_dir_all(output).map_err(|source| printonair::Error::Write {
            path: output.to_path_buf(),
            source,
        })?;
        write_file(&output.join("profile.svg"), &[file], &p.profile)?;
        write_file(&output.join("top.svg"), &[file], &p.top)?;
        write_file(&output.join("index.html"), &[file], &p.page)?;
    }
    eprintln!(
        "poa: layer-less print: {} points judged, {} unsupported, {} collisions; wrote {}",
        p.report.points,
        p.report.unsupported,
        p.report.collisions,
        output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `preview --regions -o DIR` writes a folder: refuse a path that is a file, or that names
/// one (`r.svg`), instead of making a folder of that name.
fn check_regions_folder(dir: &std::path::Path, input: &std::path::Path) -> anyhow::Result<()> {
    output::check_not_input(dir, &[input])?;
    let looks_like_file = dir
        .extension()
        .is_some_and(|e| ["svg", "html", "htm", "gcode"].contains(&e.to_string_lossy().as_ref()));
    anyhow::ensure!(
        (!dir.exists() || dir.is_dir()) && !looks_like_file,
        "--regions writes a folder of SVG files and an index.html; -o {} is a file name (use --layer N -o FILE.svg for one layer)",
        dir.display()
    );
    Ok(())
}

/// `poa check` of a layer-less (helical) print: every point judged in 3D against all
/// earlier material. `None` when the file is not one (the layered check runs instead).
fn check_layerless(
    file: &Path,
    config: printonair::layers::SlicerConfig,
    json: bool,
    fail_in_air: Option<f64>,
) -> anyhow::Result<Option<ExitCode>> {
    use printonair::helix;
    // Read a line at a time (twice, and once more for a helix): a layered plate of any size
    // is told from a vase without holding it.
    let src = helix::FileSource(file);
    let h = match helix::find_in(&src) {
        Ok(h) => h,
        Err(printonair::Error::Refused(_)) => return Ok(None),
        Err(e) => return Err(e.into()),
    };
    let bead = helix::bead_of(&config, &h);
    let rep = helix::printable::check_in(&src, &h, bead, 0)?;
    if json {
        #[derive(serde::Serialize)]
        struct Out<'a> {
            file: String,
            layerless: bool,
            helix_turns: f64,
            pitch_mm: f64,
            report: &'a helix::printable::Report,
        }
        emit_json(&Out {
            file: file.display().to_string(),
            layerless: true,
            helix_turns: h.turns,
            pitch_mm: h.pitch,
            report: &rep,
        })?;
    } else {
        let mut t = format!(
            "{}: layer-less (helical) print, {:.1} turns of {:.3} mm from Z {:.2} to {:.2}\n\
             points judged {}: unsupported {} ({:.1} mm in air), collisions {}, lift out of range {}, too steep {}; largest lean {:.1} deg\n",
            file.display(),
            h.turns,
            h.pitch,
            h.z0,
            h.z_top,
            rep.points,
            rep.unsupported,
            rep.in_air_mm,
            rep.collisions,
            rep.lift_out_of_range,
            rep.too_steep,
            rep.max_lean_deg
        );
        match &rep.first {
            None => t.push_str("every point rests on earlier material; no collision\n"),
            Some(f) => t.push_str(&format!("first failing point: {f}\n")),
        }
        write_stdout(&t)?;
    }
    if let Some(limit) = fail_in_air {
        if rep.in_air_mm > limit || rep.collisions > 0 {
            eprintln!(
                "poa: {:.1} mm in air and {} collisions (limit {limit} mm in air)",
                rep.in_air_mm, rep.collisions
            );
            return Ok(Some(ExitCode::from(2)));
        }
    }
    Ok(Some(ExitCode::SUCCESS))
}

/// `poa deform`.
pub fn deform(args: DeformArgs) -> anyhow::Result<ExitCode> {
    use printonair::helix::deform::{Frame, Spec};
    let mut params = Vec::new();
    for p in &args.params {
        let (k, v) = p
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--param takes NAME=VALUE, got `{p}`"))?;
        let v: f64 = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| anyhow::anyhow!("--param {k}: `{v}` is not a number"))?;
        let k = k.trim();
        anyhow::ensure!(
            !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
            "--param name `{k}` must be letters, digits and _"
        );
        params.push((k.to_string(), v));
    }
    let mut spec = match (&args.preset, &args.cylindrical, &args.cartesian) {
        (Some(p), None, None) => Spec::preset(p, &params)?,
        (None, Some(e), None) => Spec::expressions(Frame::Cylindrical, e, &params)?,
        (None, None, Some(e)) => Spec::expressions(Frame::Cartesian, e, &params)?,
        _ => anyhow::bail!("give one of --preset, --cylindrical, --cartesian"),
    };
    spec.cross_section = args.cross_section.clone();
    spec.speed = args.speed.clone();
    spec.chord = args.chord;
    if let Some(c) = &args.center {
        let v = crate::parse_numbers(c, 2, "--center")?;
        spec.center = Some([v[0], v[1]]);
    }
    let done = rewrite::deform_file(
        &args.file,
        &args.output,
        &spec,
        args.force,
        args.preview.as_deref(),
    )?;
    let d = &done.deformed;
    if let Some(f) = &d.check.first {
        eprintln!("poa: warning: written with --force although not printable: {f}");
    }
    if args.json {
        #[derive(serde::Serialize)]
        struct Out<'a> {
            output: String,
            turns: f64,
            pitch_mm: f64,
            center: [f64; 2],
            lines_rewritten: u64,
            moves_written: u64,
            time_in_s: f64,
            time_out_s: f64,
            check: &'a printonair::helix::printable::Report,
        }
        emit_json(&Out {
            output: args.output.display().to_string(),
            turns: d.helix.turns,
            pitch_mm: d.helix.pitch,
            center: d.helix.center,
            lines_rewritten: d.lines_rewritten,
            moves_written: d.pieces,
            time_in_s: d.time_in,
            time_out_s: d.time_out,
            check: &d.check,
        })?;
    } else {
        write_stdout(&format!(
            "{}: {:.1} turns of {:.3} mm around ({:.2}, {:.2}) deformed; {} moves written for {} lines; time {} -> {}; {}\n",
            args.output.display(),
            d.helix.turns,
            d.helix.pitch,
            d.helix.center[0],
            d.helix.center[1],
            d.pieces,
            d.lines_rewritten,
            printonair::estimate::format_dhms(d.time_in),
            printonair::estimate::format_dhms(d.time_out),
            if d.check.ok() {
                format!("printable (largest lean {:.1} deg)", d.check.max_lean_deg)
            } else {
                "NOT printable (--force)".to_string()
            }
        ))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `poa texture`.
pub fn texture(args: TextureArgs) -> anyhow::Result<ExitCode> {
    let spec = args.spec()?;
    let done = rewrite::texture_file(&args.file, &args.output, &spec, args.preview.as_deref())?;
    let t = &done.textured;
    let [vmin, vmax] = t.achieved();
    let texel = t.min_texel(spec.speeds);
    if args.json {
        #[derive(serde::Serialize)]
        struct Out {
            output: String,
            pieces: usize,
            lines_rewritten: u64,
            piece_mm: f64,
            speed_asked: [f64; 2],
            speed_reached: [f64; 2],
            acceleration: f64,
            min_texel_mm: f64,
            time_in_s: f64,
            time_out_s: f64,
            filament_in_mm: f64,
            filament_out_mm: f64,
        }
        emit_json(&Out {
            output: args.output.display().to_string(),
            pieces: t.pieces.len(),
            lines_rewritten: t.lines_rewritten,
            piece_mm: t.piece_len,
            speed_asked: spec.speeds,
            speed_reached: [vmin, vmax],
            acceleration: t.acceleration,
            min_texel_mm: texel,
            time_in_s: t.time_in,
            time_out_s: t.time_out,
            filament_in_mm: t.filament_in,
            filament_out_mm: t.filament_out,
        })?;
    } else {
        write_stdout(&format!(
            "{}: {} moves textured in {} pieces of up to {:.2} mm; speed {:.0} -> {:.0} mm/s asked, {:.1} -> {:.1} reached ({:.0} -> {:.0} mm/s needs {:.2} mm at {:.0} mm/s2); time {} -> {}\n",
            args.output.display(),
            t.lines_rewritten,
            t.pieces.len(),
            t.piece_len,
            spec.speeds[0],
            spec.speeds[1],
            vmin,
            vmax,
            spec.speeds[0],
            spec.speeds[1],
            texel,
            t.acceleration,
            printonair::estimate::format_dhms(t.time_in),
            printonair::estimate::format_dhms(t.time_out),
        ))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `poa machines [NAME]`.
pub fn machines(name: Option<&str>) -> anyhow::Result<ExitCode> {
    use printonair::fiveaxis::kinematics::{Machine, BUILT_INS};
    match name {
        None => {
            let mut t = String::from(
                "built-in five-axis machines (poa machines NAME prints one to copy):\n",
            );
            for (n, yaml) in BUILT_INS {
                let m = Machine::from_yaml(yaml)?;
                t.push_str(&format!(
                    "  {n:<8} {:?} layout, {:?}, tilt {} [{}, {}] deg\n",
                    m.layout, m.flavour, m.tilt_letter, m.limit_tilt[0], m.limit_tilt[1]
                ));
            }
            write_stdout(&t)?;
        }
        Some(n) => {
            let Some((_, yaml)) = BUILT_INS.iter().find(|(b, _)| *b == n) else {
                let names: Vec<&str> = BUILT_INS.iter().map(|(b, _)| *b).collect();
                anyhow::bail!(
                    "no built-in machine `{n}`; the built-ins are {}",
                    names.join(", ")
                );
            };
            write_stdout(yaml)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Joint G-code from a workpiece path, written atomically; a one-line summary.
fn write_joints(
    path: &[printonair::fiveaxis::sweep::PathPoint],
    machine: &str,
    set: &printonair::fiveaxis::Convert,
    out: &Path,
    inputs: &[&Path],
    preview: Option<&Path>,
) -> anyhow::Result<()> {
    use printonair::fiveaxis::{convert, kinematics::Machine};
    let m = Machine::load(machine)?;
    let c = convert(path, &m, set)?;
    output::write_bytes(out, inputs, c.text.as_bytes())?;
    if let Some(dir) = preview {
        let page = printonair::fiveaxis::preview_page(
            path,
            Some((&c, &m)),
            &format!("poa five-axis: {}", out.display()),
        );
        write_page(dir, inputs, &page)?;
    }
    let tilts: Vec<f64> = c.poses.iter().map(|(j, _, _)| m.written(j).0).collect();
    let lo = tilts.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = tilts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    write_stdout(&format!(
        "{}: {} joint moves for `{}`, {} from {lo:.1} to {hi:.1} deg; {} and {:.0} mm of filament at {} mm/s\n",
        out.display(),
        c.moves,
        m.name,
        m.tilt_letter,
        printonair::estimate::format_dhms(c.time_s),
        c.filament_mm,
        set.speed
    ))?;
    Ok(())
}

/// `poa five-axis`.
pub fn five_axis(args: FiveAxisArgs) -> anyhow::Result<ExitCode> {
    output::check_not_input(&args.output, &[&args.file])?;
    let data = input::read_all(&args.file)?;
    let is_csv = args
        .file
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    let path = if is_csv {
        printonair::fiveaxis::path_from_csv(&String::from_utf8_lossy(&data))
    } else {
        printonair::fiveaxis::path_from_gcode(&data)
    }
    .map_err(|e| anyhow::anyhow!("{}: {e}", args.file.display()))?;
    write_joints(
        &path,
        &args.machine,
        &args.joints.convert(),
        &args.output,
        &[&args.file],
        None,
    )?;
    Ok(ExitCode::SUCCESS)
}

/// `poa sweep`.
pub fn sweep(args: SweepArgs) -> anyhow::Result<ExitCode> {
    use printonair::fiveaxis::sweep::{sweep, Curve, Section, SweepSettings};
    let mut inputs: Vec<&Path> = Vec::new();
    let curve = match (&args.curve, &args.preset) {
        (Some(p), None) => {
            inputs.push(p);
            let data = input::read_all(p)?;
            Curve::csv(&String::from_utf8_lossy(&data))?
        }
        (None, Some(preset)) => Curve::preset(preset)?,
        _ => anyhow::bail!("give one of --curve, --preset"),
    };
    output::check_not_input(&args.output, &inputs)?;
    let at = crate::parse_numbers(&args.at, 2, "--at")?;
    anyhow::ensure!(
        args.filament.is_finite() && (1.0..=3.5).contains(&args.filament),
        "--filament {}: 1 to 3.5 mm",
        args.filament
    );
    let set = SweepSettings {
        width: args.width,
        height: args.layer_height,
        filament_area: printonair::layers::filament_area(args.filament),
        at: [at[0], at[1]],
    };
    let section = Section::parse(&args.section)?;
    let path = sweep(&curve, section, &set)?;
    if let Some(stl) = &args.stl {
        output::check_not_input(stl, &inputs)?;
        let mesh = printonair::fiveaxis::sweep::stl(&curve, section, set.at);
        output::write_bytes(stl, &inputs, mesh.as_bytes())?;
    }
    match &args.machine {
        Some(m) => write_joints(
            &path,
            m,
            &args.joints.convert(),
            &args.output,
            &inputs,
            args.preview.as_deref(),
        )?,
        None => {
            let text = printonair::fiveaxis::workpiece_gcode(&path, args.joints.speed);
            output::write_bytes(&args.output, &inputs, text.as_bytes())?;
            if let Some(dir) = &args.preview {
                let page = printonair::fiveaxis::preview_page(
                    &path,
                    None,
                    &format!("poa sweep: {}", args.output.display()),
                );
                write_page(dir, &inputs, &page)?;
            }
            let layers = path.last().map_or(0, |p| p.layer + 1);
            write_stdout(&format!(
                "{}: {layers} layers normal to a {:.1} mm line, {} points, one continuous path (give --machine for joint G-code)\n",
                args.output.display(),
                curve.length(),
                path.len()
            ))?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `poa check --machine M FILE`: five-axis joint G-code replayed in the workpiece frame.
fn check_joints(
    file: &Path,
    machine: &str,
    width: f64,
    height: f64,
    json: bool,
    fail_in_air: Option<f64>,
) -> anyhow::Result<ExitCode> {
    use printonair::fiveaxis::{check_joints, kinematics::Machine};
    anyhow::ensure!(
        (0.1..=3.0).contains(&width) && (0.02..=width).contains(&height),
        "--width {width} --layer-height {height}: width 0.1-3 mm, height 0.02 mm up to the width"
    );
    let m = Machine::load(machine)?;
    let data = input::read_all(file)?;
    let r = check_joints(&String::from_utf8_lossy(&data), &m, width, height);
    if json {
        emit_json(&r)?;
    } else {
        write_stdout(&format!(
            "{}: five-axis joint G-code for `{}`, replayed on the workpiece: {} moves, {:.0} mm printed; {} of {} points unsupported ({:.1} mm in air){}; {} from {:.1} to {:.1} deg, {} from {:.1} to {:.1} deg; {} poses outside the limits\n",
            file.display(),
            m.name,
            r.moves,
            r.length_mm,
            r.unsupported,
            r.points,
            r.in_air_mm,
            r.first_unsupported
                .map(|p| format!(", the first at {:.3} {:.3} {:.3}", p[0], p[1], p[2]))
                .unwrap_or_default(),
            m.tilt_letter,
            r.tilt_deg[0],
            r.tilt_deg[1],
            m.turn_letter,
            r.turn_deg[0],
            r.turn_deg[1],
            r.outside_limits
        ))?;
    }
    if r.outside_limits > 0 || fail_in_air.is_some_and(|l| r.in_air_mm > l) {
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes `page` as `DIR/index.html` (the folder made if needed), never onto an input.
fn write_page(dir: &Path, inputs: &[&Path], page: &str) -> anyhow::Result<()> {
    output::check_not_input(dir, inputs)?;
    anyhow::ensure!(
        !dir.exists() || dir.is_dir(),
        "--preview {}: not a folder (it writes index.html into one)",
        dir.display()
    );
    std::fs::create_dir_all(dir).map_err(|source| printonair::Error::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    write_file(&dir.join("index.html"), inputs, page)?;
    Ok(())
}
