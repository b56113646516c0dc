//! What `poa` prints: reports as text or JSON on stdout, error chains once on stderr, the
//! one-line summaries of rewrites, and a progress bar on a terminal.

use printonair::emit::{self, ProcessReport};

/// The error and its causes, each said once (a library error often states its cause in its
/// own message already).
pub fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if !text.contains(&c) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&c);
        }
    }
    text
}

pub fn write_stdout(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}

pub fn emit_json<T: serde::Serialize>(value: &T) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    serde_json::to_writer_pretty(&mut out, value).map_err(std::io::Error::from)?;
    writeln!(out)?;
    Ok(())
}

/// Writes a report to stdout, as text or JSON.
pub fn emit<T: serde::Serialize + std::fmt::Display>(report: &T, json: bool) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if json {
        serde_json::to_writer_pretty(&mut out, report).map_err(std::io::Error::from)?;
        writeln!(out)?;
    } else {
        write!(out, "{report}")?;
    }
    out.flush()?;
    Ok(())
}

/// One line saying what a rewrite did to `file`.
pub fn summary_line(
    file: &std::path::Path,
    report: Option<&ProcessReport>,
    dry_run: bool,
) -> String {
    let Some(r) = report else {
        return format!(
            "{}: already processed by poa; left unchanged\n",
            file.display()
        );
    };
    let mut line = format!(
        "{}: {} region{} found, {} rewritten with {} loops{}; filament {:+.1} mm, time {:+.0} s{}\n",
        file.display(),
        r.regions_found,
        if r.regions_found == 1 { "" } else { "s" },
        r.regions_rewritten,
        r.loops,
        match r.gradual {
            0 => String::new(),
            n => format!(
                " ({n} gradual overhang{} with the perimeter moved onto the layer below)",
                if n == 1 { "" } else { "s" }
            ),
        },
        r.filament_added_mm,
        r.time_added_s,
        if dry_run {
            " (dry run: nothing written)"
        } else {
            ""
        }
    );
    for note in &r.notes {
        line.push_str(&format!("  note: {note}\n"));
    }
    line
}

/// One line per region of a rewrite, for `-v`.
pub fn verbose_lines(report: &ProcessReport) -> String {
    let mut t = String::new();
    for s in &report.rewrites {
        t.push_str(&format!(
            "poa: region {} on layer {} (Z {:.2}): {} loops{}, {} strands, {:.0} mm written, {:.0} mm taken out, filament {:+.1} mm, time {:+.0} s\n",
            s.region,
            s.layer,
            s.z,
            s.loops,
            if s.gradual {
                " + perimeter moved onto the layer below"
            } else {
                ""
            },
            s.strands,
            s.written_length_mm,
            s.removed_length_mm,
            s.written_filament_mm - s.removed_filament_mm,
            s.time_added_s
        ));
    }
    for s in &report.skipped {
        t.push_str(&format!("poa: {}\n", skipped_line(s)));
    }
    t
}

pub fn skipped_line(s: &emit::SkippedRegion) -> String {
    format!(
        "region {} (layer {}, {}) left as sliced: {}",
        s.region,
        s.layer,
        s.kind.name(),
        s.reason
    )
}

/// Counts what the pipeline reads and shows it as a progress bar on stderr, only when stderr
/// is a terminal (a slicer running poa sees nothing) and the file is big enough to wait for.
pub struct Progress<R> {
    inner: R,
    bar: Option<indicatif::ProgressBar>,
}

impl<R> Progress<R> {
    pub fn new(inner: R, size: u64, wanted: bool) -> Self {
        use std::io::IsTerminal;
        let show = wanted && size > 16 * 1024 * 1024 && std::io::stderr().is_terminal();
        let bar = show.then(|| {
            let bar = indicatif::ProgressBar::new(size);
            bar.set_style(
                indicatif::ProgressStyle::with_template("poa {bar:40} {bytes}/{total_bytes} {eta}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar
        });
        Progress { inner, bar }
    }
}

impl<R: std::io::Read> std::io::Read for Progress<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(b) = &self.bar {
            b.inc(n as u64);
        }
        Ok(n)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for Progress<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        if let Some(b) = &self.bar {
            b.inc(amt as u64);
        }
        self.inner.consume(amt);
    }
}

impl<R> Drop for Progress<R> {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
