//! The whole rewrite of a file, as every command that writes G-code runs it.
//!
//! Input: an input path, a destination (none for a dry run), every input of the run (no output
//! may land on one), and a [`Request`]: the profile, the flags as `key=value` pairs, object
//! patterns, whether progress lines stay as they are. Output: the destination holding the
//! rewrite, and the [`ProcessReport`].
//!
//! Stages, in order: open ([`crate::input`]: checks, slicer settings) -> settings resolved for
//! this file ([`crate::settings`]) -> region detection, Print-on-Air pass and splice
//! ([`crate::emit::process`], which copies every other line byte for byte and updates the
//! footer) -> finish (the `M73` progress lines get the added time; binary G-code is encoded
//! again block by block) -> atomic write ([`crate::output`]). A text file rewritten into a
//! regular file is written once, assembled from the input's stretches and the made text
//! ([`crate::assemble`]); the other cases stream into a temporary file and fix the progress
//! lines in a second pass. A file poa rewrote before is
//! left alone (`Ok(None)`). [`convert_file`] (`poa convert`, text <-> binary G-code) streams
//! the file through [`crate::bgcode::stream`] into the atomic write, in bounded memory.

use std::io::{BufRead, Read};
use std::path::Path;

use crate::emit::{self, ObjectFilter, ProcessOptions, ProcessReport};
use crate::error::{Error, Result};
use crate::layers::SlicerConfig;
use crate::{assemble, bgcode, input, output, progress, settings};

/// What the user asked of a rewrite, before the file's own settings are known.
#[derive(Debug, Clone, Default)]
pub struct Request {
    /// `--profile`: a built-in name or a YAML file.
    pub profile: Option<String>,
    /// Named flags and `--set` pairs, in precedence order.
    pub flags: Vec<(String, String)>,
    /// `--objects` / `--skip-objects` patterns.
    pub objects: Vec<String>,
    pub skip_objects: Vec<String>,
    /// Leave the slicer's `M73` lines as they are.
    pub keep_progress: bool,
    /// A texture applied after the rewrite, in the same run (`--texture`).
    pub texture: Option<crate::texture::Spec>,
}

impl Request {
    /// The settings in force for a file with `config`.
    pub fn effective(&self, config: &SlicerConfig) -> Result<settings::Effective> {
        settings::resolve(self.profile.as_deref(), config, &self.flags)
            .map_err(|e| Error::Invalid(e.to_string()))
    }

    /// The pipeline's options for a file with `config`, header line included.
    pub fn options(&self, config: &SlicerConfig) -> Result<ProcessOptions> {
        let objects = ObjectFilter::from_globs(&self.objects, &self.skip_objects)?;
        let eff = self.effective(config)?;
        let mut header = format!("{} {}:", emit::HEADER_MARK, env!("CARGO_PKG_VERSION"));
        if let Some(p) = &eff.profile {
            header.push_str(&format!(" profile {p};"));
        }
        let poa = eff.poa_settings();
        let motion = emit::Motion::from_config(config, &poa);
        header.push_str(&format!(" loops at {};", motion.loop_speed));
        header.push(' ');
        header.push_str(&eff.summary());
        Ok(ProcessOptions {
            detect: eff.detect_options(config),
            settings: poa,
            objects,
            header,
        })
    }

    /// Whether the rewrite added time before progress lines that should show it.
    fn updates_progress(&self, report: &ProcessReport) -> bool {
        !self.keep_progress && report.has_progress_lines && !report.progress.is_empty()
    }
}

/// Wraps the text reader (a progress bar, say); gets the file's size.
pub type Wrap<'a> = &'a (dyn Fn(Box<dyn BufRead + Send>, u64) -> Box<dyn BufRead + Send> + Sync);

/// Rewrites `file` into `dest` (which may be `file` itself, for slicer mode; `None` is a dry
/// run). Returns `None` when the file was already rewritten by poa and is left as it is.
pub fn rewrite_file(
    file: &Path,
    dest: Option<&Path>,
    inputs: &[&Path],
    req: &Request,
    wrap: Wrap<'_>,
) -> Result<Option<ProcessReport>> {
    rewrite_file_with(file, dest, inputs, req, wrap, true)
}

/// [`rewrite_file`]; `assembled`: a text file into a regular file is written once, assembled
/// from the input's stretches and the rewrite's made text ([`crate::assemble`]), rather than
/// streamed into a temporary file and copied again for its progress lines.
///
/// Long by design: the whole rewrite of one file in pipeline order (open, passes, finish, binary re-encoding, atomic write) so that every error path is visible next to the write it guards.
fn rewrite_file_with(
    file: &Path,
    dest: Option<&Path>,
    inputs: &[&Path],
    req: &Request,
    wrap: Wrap<'_>,
    assembled: bool,
) -> Result<Option<ProcessReport>> {
    let opened = input::open(file)?;
    let input_file = opened.file;
    if emit::already_processed(&opened.head) {
        return Ok(None);
    }
    let opts = req.options(&opened.config)?;
    let totals = progress::Totals::of(&opened.config);
    let reader = wrap(opened.reader, opened.size);
    let read_err = |source| Error::Read {
        path: file.to_path_buf(),
        source,
    };
    // Reading and writing share the stream; say which side failed.
    let stream_err = |e: std::io::Error, dest: &Path| -> Error {
        if matches!(
            e.kind(),
            std::io::ErrorKind::Other
                | std::io::ErrorKind::InvalidData
                | std::io::ErrorKind::AlreadyExists
        ) {
            read_err(e)
        } else {
            Error::Write {
                path: dest.to_path_buf(),
                source: e,
            }
        }
    };
    let filter_err = |report: &ProcessReport| -> Result<()> {
        object_filter_matches(file, report, &opts.objects)
    };
    let config = opened.config;
    let texture_config = req.texture.as_ref().map(|_| config.clone());
    // The rewrite itself, into the first temporary file.
    let first_pass = |w: &mut (dyn emit::Sink + Send), dest: &Path| {
        let report = emit::process(reader, config, &opts, w).map_err(|e| stream_err(e, dest))?;
        filter_err(&report)?;
        Ok(report)
    };
    let result = if let Some(spec) = &req.texture {
        if opened.binary.is_some() {
            Err(Error::Invalid(format!(
                "{} is binary G-code; --texture works on text (`poa convert` it first)",
                file.display()
            )))
        } else {
            // Print-on-Air, then the texture on its output, both in memory: the file is
            // replaced once, or not at all. (A closure: errors go to the match below, which
            // knows a file poa rewrote before.)
            (|| -> Result<ProcessReport> {
                let sink = dest.unwrap_or(file);
                let mut text = Vec::new();
                let mut report = first_pass(&mut emit::Plain(&mut text), sink)?;
                if req.updates_progress(&report) {
                    let mut fixed = Vec::with_capacity(text.len());
                    progress::update(&text[..], &mut fixed, &report.progress, totals).map_err(
                        |source| Error::Write {
                            path: sink.to_path_buf(),
                            source,
                        },
                    )?;
                    text = fixed;
                }
                let poa_added = report.time_added_s;
                let textured = crate::texture::texture_text(
                    &text,
                    texture_config.as_ref().unwrap_or(&SlicerConfig::default()),
                    spec,
                    progress::Totals {
                        normal: totals.normal.map(|t| t + poa_added),
                        silent: totals.silent.map(|t| t + poa_added),
                    },
                )
                .map_err(|e| match e {
                    Error::Invalid(m) => Error::Invalid(format!("{}: {m}", file.display())),
                    other => other,
                })?;
                report.time_added_s += textured.time_out - textured.time_in;
                report.filament_added_mm += textured.filament_out - textured.filament_in;
                if let Some(dest) = dest {
                    output::write_bytes(dest, inputs, &textured.text)?;
                }
                Ok(report)
            })()
        }
    } else {
        match (dest, opened.binary) {
            (Some(dest), Some(mut layout)) => output::write_atomic_twice(
                dest,
                inputs,
                // Binary G-code: the rewritten text goes to a first temporary file, then into G-code
                // blocks after the metadata, which states the new totals.
                |w| first_pass(&mut emit::Plain(w), dest),
                |_| true,
                |report, written, w| {
                    emit::update_binary_metadata(&mut layout.other, report);
                    let werr = |source| Error::Write {
                        path: dest.to_path_buf(),
                        source,
                    };
                    let mut blocks = bgcode::stream::GcodeWriter::new(w, &layout).map_err(werr)?;
                    if req.updates_progress(report) {
                        progress::update(written, &mut blocks, &report.progress, totals)
                            .map_err(werr)?;
                    } else {
                        std::io::copy(&mut std::io::BufReader::new(written), &mut blocks)
                            .map_err(werr)?;
                    }
                    blocks.finish().map_err(werr)?;
                    Ok(())
                },
            ),
            (Some(dest), None) if assembled && output::replaces_file(dest, inputs)? => {
                let Some(input_file) = input_file else {
                    return rewrite_file_with(file, Some(dest), inputs, req, wrap, false);
                };
                let mut recorder = assemble::Recorder::new();
                match first_pass(&mut recorder, dest) {
                    // More pieces and progress lines than the recorder lists: streamed.
                    Ok(_) if recorder.overflowed() => {
                        return rewrite_file_with(file, Some(dest), inputs, req, wrap, false)
                    }
                    Ok(report) => output::write_atomic_at(dest, inputs, |out| {
                        let progress = req
                            .updates_progress(&report)
                            .then_some((&report.progress[..], totals));
                        recorder
                            .write(&input_file, out, progress)
                            .map_err(|f| match f {
                                assemble::Failure::Read(e) => read_err(e),
                                assemble::Failure::Write(source) => Error::Write {
                                    path: dest.to_path_buf(),
                                    source,
                                },
                            })
                    })
                    .map(|_| report),
                    // (A file rewritten before comes out of the match below as `None`.)
                    Err(e) => Err(e),
                }
            }
            (Some(dest), None) => output::write_atomic_twice(
                dest,
                inputs,
                |w| first_pass(&mut emit::Plain(w), dest),
                |report| req.updates_progress(report),
                // The progress lines precede the layers that added time: a second pass over the
                // written text gives them the new times.
                |report, written, w| {
                    progress::update(written, w, &report.progress, totals)
                        .map(|_| ())
                        .map_err(|source| Error::Write {
                            path: dest.to_path_buf(),
                            source,
                        })
                },
            ),
            (None, _) => first_pass(&mut emit::Plain(std::io::sink()), file),
        }
    };
    match result {
        Ok(r) => Ok(Some(r)),
        // poa's header line past the head of the file: rewritten before, nothing written now.
        Err(Error::Read { source, .. }) if emit::is_already_processed(&source) => Ok(None),
        Err(e) => Err(e),
    }
}

/// `--objects` / `--skip-objects` patterns must each name an object of the file: a typo would
/// otherwise rewrite nothing (or everything) without a word.
fn object_filter_matches(file: &Path, report: &ProcessReport, filter: &ObjectFilter) -> Result<()> {
    let missing = filter.unmatched(&report.objects);
    if missing.is_empty() {
        return Ok(());
    }
    let objects = if report.objects.is_empty() {
        "it labels no objects".to_string()
    } else {
        format!("its objects: {}", report.objects.join(", "))
    };
    Err(Error::Invalid(format!(
        "object pattern {} matches no object of {}; {objects} (`poa info` lists them)",
        missing
            .iter()
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", "),
        file.display()
    )))
}

/// Copies `file` to `dest` as it is (a file poa rewrote before), atomically.
pub fn copy_file(file: &Path, dest: &Path, inputs: &[&Path]) -> Result<()> {
    let mut src = std::fs::File::open(file).map_err(|source| Error::Read {
        path: file.to_path_buf(),
        source,
    })?;
    output::write_atomic(dest, inputs, |w| {
        std::io::copy(&mut src, w)
            .map(|_| ())
            .map_err(|source| Error::Write {
                path: dest.to_path_buf(),
                source,
            })
    })
}

/// What [`ab_plate`] made.
#[derive(Debug, Clone)]
pub struct AbOutcome {
    pub copy_name: String,
    pub layers: usize,
    pub report: ProcessReport,
}

/// `poa ab`: the A/B plate of `file` into `out`, the copy rewritten with Print-on-Air; its
/// footer and progress lines count the copy and the loops.
pub fn ab_plate(
    file: &Path,
    out: &Path,
    ab: &crate::ab::AbOptions,
    req: &Request,
) -> Result<AbOutcome> {
    output::check_not_input(out, &[file])?;
    let mut opened = input::open(file)?;
    if emit::already_processed(&opened.head) {
        return Err(Error::Invalid(format!(
            "{} was already rewritten by poa; make the A/B plate from the slicer's original",
            file.display()
        )));
    }
    let read_err = |source| Error::Read {
        path: file.to_path_buf(),
        source,
    };
    let mut text = Vec::new();
    opened.reader.read_to_end(&mut text).map_err(read_err)?;
    let plate = crate::ab::build(&text, &opened.config, ab).map_err(|e| {
        Error::Invalid(format!(
            "cannot make an A/B plate of {}: {e}",
            file.display()
        ))
    })?;
    let mut opts = req.options(&opened.config)?;
    opts.objects = ObjectFilter::from_globs(&plate.copy_names, &[])?;
    // The statistics and progress lines count the copy too.
    let totals = progress::Totals::of(&opened.config);
    let mut text = Vec::with_capacity(plate.text.len());
    progress::update(&plate.text[..], &mut text, &plate.added, totals).map_err(read_err)?;
    let footer = footer_start(&text);
    let fa = opened.config.e_area();
    let tail = progress::update_footer(
        &text[footer..],
        plate.added_filament_mm,
        plate.added_time_s,
        fa,
        opened.config.filament_density(),
    );
    text.truncate(footer);
    text.extend_from_slice(&tail);
    let scale = match (totals.normal, totals.silent) {
        (Some(n), Some(s)) if n > 0.0 => s / n,
        _ => 1.0,
    };
    let totals = progress::Totals {
        normal: totals.normal.map(|t| t + plate.added_time_s),
        silent: totals.silent.map(|t| t + plate.added_time_s * scale),
    };
    let mut result = Vec::new();
    let report = emit::process(
        &text[..],
        opened.config,
        &opts,
        &mut emit::Plain(&mut result),
    )
    .map_err(read_err)?;
    if req.updates_progress(&report) {
        let mut fixed = Vec::with_capacity(result.len());
        progress::update(&result[..], &mut fixed, &report.progress, totals).map_err(read_err)?;
        result = fixed;
    }
    let bytes = match opened.binary {
        Some(mut layout) => {
            emit::update_binary_metadata(&mut layout.other, &report);
            let werr = |source| Error::Write {
                path: out.to_path_buf(),
                source,
            };
            let mut blocks = bgcode::stream::GcodeWriter::new(Vec::new(), &layout).map_err(werr)?;
            std::io::Write::write_all(&mut blocks, &result).map_err(werr)?;
            blocks.finish().map_err(werr)?
        }
        None => result,
    };
    output::write_bytes(out, &[file], &bytes)?;
    Ok(AbOutcome {
        copy_name: plate.copy_name,
        layers: plate.layers,
        report,
    })
}

/// Start of the line where the last 64 KiB of `text` begin: the statistics footer lies there.
fn footer_start(text: &[u8]) -> usize {
    let from = text.len().saturating_sub(64 * 1024);
    if from == 0 {
        return 0;
    }
    text[from..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(text.len(), |i| from + i + 1)
}

/// `poa convert`: binary G-code to text, or PrusaSlicer text to binary (`libbgcode`: the
/// reference converter's settings, print metadata uncompressed), whichever `input` is (by its
/// first bytes). Streamed both ways ([`bgcode::stream::to_ascii`],
/// [`bgcode::stream::from_ascii`]), so memory stays bounded (one line, one block and the
/// metadata) whatever the file's size; the bytes are those of the whole-file converters. A
/// refusal leaves `out` as it was (the atomic write: a device or pipe is given nothing).
pub fn convert_file(input: &Path, out: &Path, libbgcode: bool) -> Result<()> {
    output::check_not_input(out, &[input])?;
    let (mut file, size) = input::open_regular(input)?;
    let read_err = |source| Error::Read {
        path: input.to_path_buf(),
        source,
    };
    let mut head = [0u8; 4];
    let n = size.min(head.len() as u64) as usize;
    file.read_exact(&mut head[..n]).map_err(read_err)?;
    let binary = bgcode::is_bgcode(&head[..n]);
    let mut config = bgcode::BinarizeConfig::prusaslicer();
    if libbgcode {
        config.print_metadata = bgcode::Compression::None;
    }
    output::write_atomic(out, &[input], |w| {
        let done = if binary {
            bgcode::stream::to_ascii(&mut file, size, w)
        } else {
            bgcode::stream::from_ascii(&mut file, size, &config, w)
        };
        done.map(drop).map_err(|e| match e {
            bgcode::stream::ConvertError::Format(e) if binary => Error::NotGcode {
                path: input.to_path_buf(),
                reason: format!("the binary G-code is damaged: {e}"),
            },
            bgcode::stream::ConvertError::Format(e) => {
                Error::Invalid(format!("{}: {e}", input.display()))
            }
            // The reader's line limit holds here too: a binary file made of a longer line
            // is one poa (and the printer) refuses to read back.
            bgcode::stream::ConvertError::LineTooLong(line) => {
                read_err(crate::gcode::line_too_long(line))
            }
            bgcode::stream::ConvertError::Read(source) => read_err(source),
            bgcode::stream::ConvertError::Write(source) => Error::Write {
                path: out.to_path_buf(),
                source,
            },
        })
    })
}

/// What `poa deform` did.
pub struct DeformOutcome {
    pub deformed: crate::helix::Deformed,
    pub bytes_in: u64,
}

/// `poa deform`: the vase-mode print `file` deformed by `spec` into `out` (atomically, never
/// onto the input); refused with the first failing point when the result is not printable,
/// unless `force`. `preview` is a folder for an HTML page with the side profile and top view.
pub fn deform_file(
    file: &Path,
    out: &Path,
    spec: &crate::helix::deform::Spec,
    force: bool,
    preview: Option<&Path>,
) -> Result<DeformOutcome> {
    let (text, config) = whole_text(file, out, preview)?;
    let deformed = crate::helix::deform_text(&text, &config, spec, force).map_err(|e| match e {
        Error::Refused(m) => Error::Refused(format!("{}: {m}", file.display())),
        other => other,
    })?;
    output::write_bytes(out, &[file], &deformed.text)?;
    if let Some(dir) = preview {
        std::fs::create_dir_all(dir).map_err(|source| Error::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        let title = format!(
            "poa deform {}: {}",
            spec.preset.as_deref().unwrap_or("expressions"),
            file.file_name()
                .map(|f| f.to_string_lossy().to_string())
                .unwrap_or_default()
        );
        let page = crate::helix::picture::page(
            &title,
            &deformed.check,
            deformed.helix_out.center,
            deformed.bead,
        );
        output::write_bytes(&dir.join("index.html"), &[file, out], page.as_bytes())?;
    }
    Ok(DeformOutcome {
        deformed,
        bytes_in: text.len() as u64,
    })
}

/// A whole-file transform's input, read whole as text with its config, once its outputs
/// (`out`, and the folder `preview`) are known not to be the input. Binary G-code is refused
/// with the command that converts it.
fn whole_text(
    file: &Path,
    out: &Path,
    preview: Option<&Path>,
) -> Result<(Vec<u8>, crate::config::SlicerConfig)> {
    output::check_not_input(out, &[file])?;
    if let Some(dir) = preview {
        output::check_not_input(dir, &[file])?;
    }
    let mut opened = input::open(file)?;
    if opened.binary.is_some() {
        return Err(Error::Invalid(format!(
            "{} is binary G-code; convert it to text first (`poa convert {} text.gcode`)",
            file.display(),
            file.display()
        )));
    }
    let mut text = Vec::new();
    opened
        .reader
        .read_to_end(&mut text)
        .map_err(|source| Error::Read {
            path: file.to_path_buf(),
            source,
        })?;
    Ok((text, opened.config))
}

/// What `poa texture` did.
pub struct TextureOutcome {
    pub textured: crate::texture::Textured,
    pub bytes_in: u64,
}

/// `poa texture`: `file` textured by `spec` into `out` (atomically, never onto the input);
/// `preview` is a folder for the HTML page of the texture and the bead widths it makes.
pub fn texture_file(
    file: &Path,
    out: &Path,
    spec: &crate::texture::Spec,
    preview: Option<&Path>,
) -> Result<TextureOutcome> {
    let (text, config) = whole_text(file, out, preview)?;
    let textured =
        crate::texture::texture_text(&text, &config, spec, progress::Totals::of(&config)).map_err(
            |e| match e {
                Error::Invalid(m) => Error::Invalid(format!("{}: {m}", file.display())),
                other => other,
            },
        )?;
    output::write_bytes(out, &[file], &textured.text)?;
    if let Some(dir) = preview {
        std::fs::create_dir_all(dir).map_err(|source| Error::Write {
            path: dir.to_path_buf(),
            source,
        })?;
        let fa = config.e_area();
        let title = format!(
            "poa texture: {}",
            file.file_name()
                .map(|f| f.to_string_lossy().to_string())
                .unwrap_or_default()
        );
        let page = crate::texture::preview_page(&textured, spec, fa, &title);
        output::write_bytes(&dir.join("index.html"), &[file, out], page.as_bytes())?;
    }
    Ok(TextureOutcome {
        textured,
        bytes_in: text.len() as u64,
    })
}
