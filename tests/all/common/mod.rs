//! Shared helpers for the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use printonair::layers::{Layer, LayerKind, LayerReader, ReaderOptions, SlicerConfig};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn samples() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("sample-gcode"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "gcode"))
        .collect();
    v.sort();
    assert!(v.len() >= 10, "sample-gcode/ should hold the samples");
    v
}

pub fn sample(name: &str) -> PathBuf {
    repo().join("sample-gcode").join(name)
}

/// Rewrites `data` with default settings (bridges as given), as `poa process` does.
pub fn rewrite(
    data: &[u8],
    bridges: printonair::poa::BridgeMode,
) -> (Vec<u8>, printonair::emit::ProcessReport) {
    use printonair::emit::{self, ObjectFilter, ProcessOptions};
    let config = SlicerConfig::parse(data);
    let opts = ProcessOptions {
        detect: printonair::report::detect_options(&config),
        settings: printonair::poa::PoaSettings {
            bridges,
            ..Default::default()
        },
        objects: ObjectFilter::default(),
        header: format!("{} test", emit::HEADER_MARK),
    };
    let mut out = Vec::new();
    let rep = emit::process(data, config, &opts, &mut printonair::emit::Plain(&mut out)).unwrap();
    (out, rep)
}

/// Every block of a file (preamble included), with raw bytes.
pub fn all_layers(data: &[u8]) -> Vec<Layer> {
    read_layers(data, true).0
}

/// Reads a file the way the CLI does (config from the file itself, no environment).
pub fn read_layers(data: &[u8], keep_raw: bool) -> (Vec<Layer>, LayerReader<&[u8]>) {
    let config = SlicerConfig::parse(data);
    let mut r = LayerReader::new(data, ReaderOptions { keep_raw, config });
    let layers = r.by_ref().map(|l| l.unwrap()).collect();
    (layers, r)
}

pub fn layer_count(layers: &[Layer]) -> usize {
    layers.iter().filter(|l| l.kind == LayerKind::Layer).count()
}

/// Removes every comment and the blank lines that leaves: the retrofit case.
pub fn strip_comments(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len());
    for line in data.split(|&b| b == b'\n') {
        let code = match line.iter().position(|&b| b == b';') {
            Some(i) => &line[..i],
            None => line,
        };
        let code = code.strip_suffix(b"\r").unwrap_or(code);
        let trimmed = code.trim_ascii_end();
        if !trimmed.is_empty() {
            out.extend_from_slice(trimmed);
            out.push(b'\n');
        }
    }
    out
}

pub fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The team's shared reference folder beside the checkout, or `None` (with a note saying
/// which test skips) on a machine that does not have it: a fresh clone has no `../shared`.
pub fn shared(test: &str) -> Option<PathBuf> {
    let p = repo().join("..").join("shared");
    if p.is_dir() {
        Some(p)
    } else {
        note(&format!(
            "{test} skipped: it uses third-party data from ../shared, which is absent"
        ));
        None
    }
}

/// Prints a note past the test harness's capture (it captures `eprintln!`, not the stream),
/// so that a skipped test shows in `cargo test` output.
pub fn note(text: &str) {
    use std::io::Write;
    // Once per text: a property test asks on every one of its cases.
    static SAID: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let mut said = SAID.lock().unwrap_or_else(|e| e.into_inner());
    if !said.iter().any(|s| s == text) {
        said.push(text.to_string());
        let _ = writeln!(std::io::stderr(), "note: {text}");
    }
}

/// Whether an external tool the test needs is installed. Under CI (`CI` set) it must be:
/// `.ci/run` installs it, so its absence fails the test instead of skipping it.
pub fn have(tool: &str, check: &[&str], install: &str) -> bool {
    let ok = std::process::Command::new(tool)
        .args(check)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "{tool} is needed under CI ({install})"
        );
        note(&format!(
            "a test skipped: {tool} is not installed ({install})"
        ));
    }
    ok
}

pub fn have_prusaslicer() -> bool {
    have(
        "prusa-slicer",
        &["--help"],
        "apt-get install -y prusa-slicer",
    )
}

/// libbgcode's Python wrapper, the independent reader of the binary G-code poa writes.
pub fn have_pybgcode() -> bool {
    have(
        "python3",
        &["-c", "import pybgcode"],
        "pip install pybgcode-jneilliii",
    )
}

/// The repository's own test parts (OpenSCAD sources and their STLs in tests/parts/).
pub fn part(name: &str) -> PathBuf {
    repo().join("tests/parts").join(format!("{name}.stl"))
}

/// Slices a test part with PrusaSlicer's CLI and the samples' config plus `args`; `None`
/// (the test skips) when PrusaSlicer is not installed outside CI.
pub fn slice(specimen: &str, args: &[&str]) -> Option<Vec<u8>> {
    slice_stl(&part(specimen), args)
}

/// Slices an STL with PrusaSlicer's CLI and the samples' config plus `args`.
pub fn slice_stl(stl: &Path, args: &[&str]) -> Option<Vec<u8>> {
    let config = repo().join("sample-gcode/config/prusaslicer-mk3s-pla.ini");
    slice_stl_from(stl, Some(&config), args)
}

/// Slices a test part with PrusaSlicer's own defaults (0.3 mm layers, widths from the
/// nozzle) plus `args`: a printer profile nobody tuned poa to.
pub fn slice_defaults(specimen: &str, args: &[&str]) -> Option<Vec<u8>> {
    slice_stl_defaults(&part(specimen), args)
}

/// [`slice_defaults`] for any model file (an AMF plate, say).
pub fn slice_stl_defaults(model: &Path, args: &[&str]) -> Option<Vec<u8>> {
    slice_stl_from(model, None, args)
}

fn slice_stl_from(stl: &Path, config: Option<&Path>, args: &[&str]) -> Option<Vec<u8>> {
    if !have_prusaslicer() {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.gcode");
    let mut cmd = std::process::Command::new("prusa-slicer");
    if let Some(config) = config {
        cmd.arg("--load").arg(config);
    }
    let o = cmd
        .args(args)
        .arg("--export-gcode")
        .arg("-o")
        .arg(&out)
        .arg(stl)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "prusa-slicer failed on {} {args:?}: {}",
        stl.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    Some(read(&out))
}

/// Line ranges (1-based, inclusive) of the blocks poa wrote.
pub fn poa_blocks(data: &[u8]) -> Vec<(u64, u64)> {
    let mut v = Vec::new();
    let mut open = None;
    for (i, line) in data.split(|&b| b == b'\n').enumerate() {
        let n = i as u64 + 1;
        if line.starts_with(b";POA_BEGIN") {
            open = Some(n);
        } else if line.starts_with(b";POA_END") {
            if let Some(s) = open.take() {
                v.push((s, n));
            }
        }
    }
    v
}

/// A triangle mesh written as ASCII STL, for test parts made on the fly.
#[derive(Default)]
pub struct Mesh {
    tris: Vec<[[f64; 3]; 3]>,
}

impl Mesh {
    /// An axis-aligned box.
    pub fn cuboid(&mut self, a: [f64; 3], b: [f64; 3]) -> &mut Self {
        let p = |i: usize| {
            [
                if i & 1 == 0 { a[0] } else { b[0] },
                if i & 2 == 0 { a[1] } else { b[1] },
                if i & 4 == 0 { a[2] } else { b[2] },
            ]
        };
        // Faces as quads of corner indices, outward winding.
        for q in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            self.tris.push([p(q[0]), p(q[1]), p(q[2])]);
            self.tris.push([p(q[0]), p(q[2]), p(q[3])]);
        }
        self
    }

    /// A vertical prism over a polygon (counter-clockwise), from z0 to z1.
    pub fn prism(&mut self, poly: &[[f64; 2]], z0: f64, z1: f64) -> &mut Self {
        let n = poly.len();
        let c = poly.iter().fold([0.0, 0.0], |s, p| {
            [s[0] + p[0] / n as f64, s[1] + p[1] / n as f64]
        });
        for i in 0..n {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            self.tris
                .push([[c[0], c[1], z1], [p[0], p[1], z1], [q[0], q[1], z1]]);
            self.tris
                .push([[c[0], c[1], z0], [q[0], q[1], z0], [p[0], p[1], z0]]);
            self.tris
                .push([[p[0], p[1], z0], [q[0], q[1], z0], [q[0], q[1], z1]]);
            self.tris
                .push([[p[0], p[1], z0], [q[0], q[1], z1], [p[0], p[1], z1]]);
        }
        self
    }

    pub fn cylinder(&mut self, c: [f64; 2], r: f64, z0: f64, z1: f64) -> &mut Self {
        let poly: Vec<[f64; 2]> = (0..96)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 96.0;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect();
        self.prism(&poly, z0, z1)
    }

    pub fn write(&self, path: &Path) {
        let mut s = String::from("solid poa_test\n");
        for t in &self.tris {
            s.push_str("facet normal 0 0 0\n outer loop\n");
            for v in t {
                s.push_str(&format!("  vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            s.push_str(" endloop\nendfacet\n");
        }
        s.push_str("endsolid poa_test\n");
        std::fs::write(path, s).unwrap();
    }
}

/// Several parts (ASCII STL files) as the objects of one AMF file, each moved by its offset
/// and sliced at its own layer height where one is given (PrusaSlicer reads AMF's
/// `slic3r.layer_height` object metadata: per-object layer heights, as set in its GUI).
pub fn write_amf(objects: &[(&Path, [f64; 2], Option<f64>)], out: &Path) {
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<amf unit=\"millimeter\" version=\"1.1\">\n",
    );
    let mut instances = String::new();
    for (k, (stl, offset, layer_height)) in objects.iter().enumerate() {
        let text = std::fs::read_to_string(stl).unwrap();
        let vertices: Vec<&str> = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("vertex "))
            .collect();
        s.push_str(&format!("<object id=\"{k}\">\n"));
        if let Some(h) = layer_height {
            s.push_str(&format!(
                "<metadata type=\"slic3r.layer_height\">{h}</metadata>\n"
            ));
        }
        s.push_str("<mesh><vertices>\n");
        for v in &vertices {
            let c: Vec<&str> = v.split_whitespace().collect();
            s.push_str(&format!(
                "<vertex><coordinates><x>{}</x><y>{}</y><z>{}</z></coordinates></vertex>\n",
                c[0], c[1], c[2]
            ));
        }
        s.push_str("</vertices><volume>\n");
        for t in 0..vertices.len() / 3 {
            s.push_str(&format!(
                "<triangle><v1>{}</v1><v2>{}</v2><v3>{}</v3></triangle>\n",
                3 * t,
                3 * t + 1,
                3 * t + 2
            ));
        }
        s.push_str("</volume></mesh></object>\n");
        instances.push_str(&format!(
            "<instance objectid=\"{k}\"><deltax>{}</deltax><deltay>{}</deltay><rz>0</rz></instance>",
            offset[0], offset[1]
        ));
    }
    s.push_str(&format!(
        "<constellation id=\"{}\">{instances}</constellation>\n</amf>\n",
        objects.len()
    ));
    std::fs::write(out, s).unwrap();
}

/// Slices a mesh with PrusaSlicer's CLI and the samples' config plus `args`.
pub fn slice_mesh(mesh: &Mesh, args: &[&str]) -> Option<Vec<u8>> {
    let dir = tempfile::tempdir().unwrap();
    let stl = dir.path().join("part.stl");
    mesh.write(&stl);
    slice_stl(&stl, args)
}

/// Cura's printer definitions (fdmprinter.def.json and the machines inheriting it): Debian
/// ships them in the `cura` GUI package, not in cura-engine. `CURA_DEFINITIONS` names the
/// folder (`.ci/run` unpacks them from `apt-get download cura`).
pub fn cura_definitions() -> Option<PathBuf> {
    let candidates = std::env::var_os("CURA_DEFINITIONS")
        .map(PathBuf::from)
        .into_iter()
        .chain([
            PathBuf::from("/usr/share/cura/resources/definitions"),
            repo().join("target/cura/usr/share/cura/resources/definitions"),
        ]);
    candidates
        .into_iter()
        .find(|d| d.join("fdmprinter.def.json").is_file())
}

/// CuraEngine and its definitions; skips with a note outside CI when either is missing.
pub fn have_cura() -> bool {
    if !have("CuraEngine", &["help"], "apt-get install -y cura-engine") {
        return false;
    }
    if cura_definitions().is_some() {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "Cura's definitions are needed under CI (set CURA_DEFINITIONS; .ci/run unpacks them)"
    );
    note("a test skipped: Cura's definitions are missing (apt-get download cura; set CURA_DEFINITIONS)");
    false
}

/// Slices `stl` with CuraEngine and the machine definition `machine` (e.g. `prusa_i3_mk3`)
/// plus `settings` (`key=value`), given globally and to extruder 0 (CuraEngine does not
/// evaluate the definitions' formulas; extruder settings shadow global ones). 1.75 mm
/// filament; the part is centred on the bed.
pub fn slice_cura(stl: &Path, machine: &str, settings: &[&str]) -> Option<Vec<u8>> {
    if !have_cura() {
        return None;
    }
    let defs = cura_definitions()?;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.gcode");
    let mut cmd = std::process::Command::new("CuraEngine");
    // Machines with extruder trains of their own (Ultimaker S5) find them beside the
    // definitions.
    let extruders = defs.with_file_name("extruders");
    if extruders.is_dir() {
        let paths = std::env::join_paths([defs.as_path(), extruders.as_path()]).unwrap();
        cmd.env("CURA_ENGINE_SEARCH_PATH", paths);
    }
    cmd.arg("slice")
        .arg("-j")
        .arg(defs.join(format!("{machine}.def.json")));
    let all: Vec<&str> = ["material_diameter=1.75", "center_object=true"]
        .into_iter()
        .chain(settings.iter().copied())
        .collect();
    for s in &all {
        cmd.arg("-s").arg(s);
    }
    cmd.arg("-e0");
    for s in &all {
        cmd.arg("-s").arg(s);
    }
    let o = cmd.arg("-l").arg(stl).arg("-o").arg(&out).output().unwrap();
    assert!(
        o.status.success(),
        "CuraEngine failed on {}: {}",
        stl.display(),
        String::from_utf8_lossy(&o.stderr)
            .lines()
            .rev()
            .take(5)
            .collect::<Vec<_>>()
            .join("\n")
    );
    Some(std::fs::read(&out).unwrap())
}

/// The `poa` binary under test.
pub fn poa() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_poa"))
}

/// Runs `poa COMMAND INPUT -o OUT ARGS...`.
pub fn poa_to(command: &str, input: &Path, out: &Path, args: &[&str]) -> std::process::Output {
    poa()
        .arg(command)
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(args)
        .output()
        .unwrap()
}

/// Runs poa through python3 and returns its output and peak RSS in KiB (`None` without
/// python3: the bound is then not measured). Measured from a small parent: Linux carries the
/// parent's peak into a spawned child's `ru_maxrss` across exec, so a child of this test
/// binary (whose tests hold files of hundreds of MB) would report the binary's peak.
pub fn peak_kib(
    args: &[&dyn AsRef<std::ffi::OsStr>],
    envs: &[(&str, &str)],
) -> (std::process::Output, Option<u64>) {
    let script = "import resource, subprocess, sys\n\
        r = subprocess.run(sys.argv[1:])\n\
        sys.stderr.write('\\nPEAK %d\\n' % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n\
        sys.exit(r.returncode)\n";
    let mut c = std::process::Command::new("python3");
    c.arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_poa"))
        .args(args);
    for (k, v) in envs {
        c.env(k, v);
    }
    match c.output() {
        Ok(mut o) => {
            let text = String::from_utf8_lossy(&o.stderr).to_string();
            let (rest, peak) = match text.rsplit_once("\nPEAK ") {
                Some((rest, p)) => (rest.to_string(), p.trim().parse().ok()),
                None => (text, None),
            };
            o.stderr = rest.into_bytes();
            (o, peak)
        }
        Err(_) => {
            note("memory bound not measured: python3 is missing");
            let mut p = poa();
            p.args(args);
            for (k, v) in envs {
                p.env(k, v);
            }
            (p.output().unwrap(), None)
        }
    }
}

/// No layer has more than 0.3 mm more in air than the slicer left.
pub fn no_layer_worse(
    what: &str,
    before: &printonair::report::CheckReport,
    after: &printonair::report::CheckReport,
) {
    for (b, a) in before.layers.iter().zip(&after.layers) {
        assert!(
            a.in_air_mm <= b.in_air_mm + 0.3,
            "{what}: layer {} {:.1} mm in air, {:.1} before",
            b.layer,
            a.in_air_mm,
            b.in_air_mm
        );
    }
}

/// The auxiliary-fan line [`as_orca`] writes after each part-fan line of a Bambu-style file.
pub const BAMBU_AUX_FAN: &str = "M106 P2 S0";

/// A PrusaSlicer file retold in OrcaSlicer's dialect, line for line: its role names ("Outer
/// wall"), its config block markers and setting names (`sparse_infill_density`), its header; with `bambu` also the tags OrcaSlicer and
/// Bambu Studio write for Bambu printers (`; FEATURE:`, `; CHANGE_LAYER`, `; Z_HEIGHT:`,
/// `; LAYER_HEIGHT:`, `; LINE_WIDTH:`), else the ones it writes for other printers (`;TYPE:`,
/// `;LAYER_CHANGE`, `;Z:`, `;HEIGHT:`, `;WIDTH:`). The moves are the same bytes: poa must
/// find and plan the same regions in both. A Bambu-style file also turns its auxiliary fan
/// off after each part-fan line ([`BAMBU_AUX_FAN`]), as Bambu Studio's layers do.
pub fn as_orca(data: &[u8], bambu: bool) -> Vec<u8> {
    const ROLES: &[(&str, &str)] = &[
        ("External perimeter", "Outer wall"),
        ("Perimeter", "Inner wall"),
        ("Overhang perimeter", "Overhang wall"),
        ("Internal infill", "Sparse infill"),
        ("Solid infill", "Internal solid infill"),
        ("Top solid infill", "Top surface"),
        ("Bridge infill", "Bridge"),
        ("Gap fill", "Gap infill"),
        ("Skirt/Brim", "Skirt"),
        ("Support material", "Support"),
        ("Support material interface", "Support interface"),
        ("Wipe tower", "Prime tower"),
    ];
    // Orca's names for the settings, as poa's table states them (checked against Bambu
    // Studio's config blocks).
    use printonair::config::ORCA_NAMES as SETTINGS;
    let text = String::from_utf8(data.to_vec()).expect("a UTF-8 PrusaSlicer file");
    let mut out = String::with_capacity(text.len() + 4096);
    for line in text.split_inclusive('\n') {
        let (body, end) = match line.strip_suffix('\n') {
            Some(b) => (b, "\n"),
            None => (line, ""),
        };
        let told: String = if body.starts_with("; generated by PrusaSlicer") {
            let who = if bambu {
                "; BambuStudio 01.09.00.70"
            } else {
                "; generated by OrcaSlicer 2.1.1 on 2026-12-07 at 10:00:00"
            };
            format!("; HEADER_BLOCK_START\n{who}\n; HEADER_BLOCK_END")
        } else if body == "; prusaslicer_config = begin" {
            "; CONFIG_BLOCK_START".into()
        } else if body == "; prusaslicer_config = end" {
            "; CONFIG_BLOCK_END".into()
        } else if let Some((key, value)) = body
            .strip_prefix("; ")
            .and_then(|kv| kv.split_once(" = "))
            .and_then(|(k, v)| SETTINGS.iter().find(|(p, _)| *p == k).map(|(_, o)| (o, v)))
        {
            format!("; {key} = {value}")
        } else if let Some(role) = body.strip_prefix(";TYPE:") {
            let name = ROLES
                .iter()
                .find(|(p, _)| *p == role)
                .map_or(role, |(_, o)| *o);
            if bambu {
                format!("; FEATURE: {name}")
            } else {
                format!(";TYPE:{name}")
            }
        } else if !bambu {
            body.into()
        } else if body == ";LAYER_CHANGE" {
            "; CHANGE_LAYER".into()
        } else if let Some(z) = body.strip_prefix(";Z:") {
            format!("; Z_HEIGHT: {z}")
        } else if let Some(h) = body.strip_prefix(";HEIGHT:") {
            format!("; LAYER_HEIGHT: {h}")
        } else if let Some(w) = body.strip_prefix(";WIDTH:") {
            format!("; LINE_WIDTH: {w}")
        } else if body == ";WIPE_START" || body == ";WIPE_END" {
            format!("; {}", &body[1..])
        } else {
            body.into()
        };
        out.push_str(&told);
        out.push_str(end);
        // Bambu Studio turns its auxiliary fan off wherever it sets the part fan.
        if bambu && body.starts_with("M106 S") {
            out.push_str(BAMBU_AUX_FAN);
            out.push('\n');
        }
    }
    out.into_bytes()
}
