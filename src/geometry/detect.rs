//! Region detection over a stream of layers.
//!
//! Input: an iterator of [`Layer`]s. Output: for each block in file order, a [`Detected`] with
//! the layer, its printed area, the printed area below it and its unsupported regions, handed
//! to a callback. Layers are processed in small batches whose geometry runs on all cores;
//! only a batch, one layer held back, the area of the layer before them and the last
//! footprint are held at once. Each layer first tries the cheap proof of
//! [`super::proof`]; a layer's area is computed only when its proof or the next layer's
//! fails, so a layer proven supported costs no polygon work.
//! Invariants: the regions are exactly those of the exact path (proof off); the areas given
//! are exactly those [`super::printed_area`] gives; a footprint is shared only between layers
//! whose outline strands are equal.

use std::collections::VecDeque;
use std::io;

use geo::MultiPolygon;
use rayon::prelude::*;

use crate::layers::{Layer, LayerKind};

use super::area::{area_from_footprint, outline_strands, Strands};
use super::proof::{supported, Support};
use super::{find_regions_as_sliced, DetectOptions, Region};

/// Layers per parallel batch: enough to keep two cores busy, few enough to keep memory flat.
const BATCH: usize = 4;
/// A batch also ends once its layers weigh this much ([`weight`]): a layer of a big plate
/// holds megabytes of strands, and two of them keep two cores busy.
const BATCH_BYTES: usize = 6 << 20;

/// One block of the file with what detection found.
pub struct Detected {
    pub layer: Layer,
    /// Printed area of this layer; `None` for the preamble, and for a layer proven supported
    /// whose area the next layer did not need either ([`Detected::area_or_compute`]).
    pub area: Option<MultiPolygon<f64>>,
    /// Printed area of the layer below (empty for the first layer and the preamble); `None`
    /// where the proof made it unneeded. Always there when `regions` are.
    pub below: Option<MultiPolygon<f64>>,
    pub regions: Vec<Region>,
}

impl Detected {
    /// A layer with no geometry computed, for passes that need none.
    pub fn plain(layer: Layer) -> Detected {
        Detected {
            layer,
            area: None,
            below: None,
            regions: Vec::new(),
        }
    }

    /// This layer's printed area, computed now if detection did not need it.
    pub fn area_or_compute(&self, opts: &DetectOptions) -> std::borrow::Cow<'_, MultiPolygon<f64>> {
        match &self.area {
            Some(a) => std::borrow::Cow::Borrowed(a),
            None if self.layer.kind == LayerKind::Layer => {
                std::borrow::Cow::Owned(super::printed_area(&self.layer, &opts.area))
            }
            None => std::borrow::Cow::Owned(MultiPolygon(Vec::new())),
        }
    }
}

/// A batch of [`BATCH`] layers or more ends once they weigh this much ([`weight`]): 200 000
/// layers of one strand each took 5.7 s in batches of four (the pool's wake-ups), 0.3 s so.
const BATCH_MIN_BYTES: usize = 64 << 10;
/// Layers handed from the reading thread to the geometry at once weigh up to this much
/// ([`weight`]); a heavier layer goes alone.
const BUNDLE_BYTES: usize = 64 << 10;
/// Whether `n` layers weighing `w` in all make a bundle to hand to another thread.
pub(crate) fn bundle_full(n: usize, w: usize) -> bool {
    w >= BUNDLE_BYTES || n >= MAX_BATCH
}

/// Most layers in a batch, however light.
const MAX_BATCH: usize = 64;

/// Bundles of layers read ahead of the geometry: enough that the byte budget below is what
/// stops the reader, so that it keeps reading through a layer whose geometry takes long (a
/// plate's caps) and the geometry does not wait for it after (16 mushrooms: it waited 15-27
/// ms with one batch ahead; analyze 162 -> 156 ms).
const READ_AHEAD: usize = 64 * BATCH;
/// ... and no more than this much of them ([`weight`]), so that peak memory stays flat
/// however big a plate's layers are. 8 MB: the 16 mushrooms' cap layers and the plans after
/// them take some 150 ms, in which the reader read 3 MB and then waited (analyze 203 -> 189
/// ms, min of 21 runs; peak RSS 25 -> 29 MB).
const READ_AHEAD_BYTES: usize = 8 << 20;

/// Bytes a layer holds: its raw text and, per segment, a point, a line number and an E.
pub fn weight(layer: &Layer) -> usize {
    layer.raw.len()
        + layer
            .paths
            .iter()
            .map(|p| p.points.len() * 32)
            .sum::<usize>()
}

/// Bytes in flight between two threads, capped at a limit: the sender waits before sending
/// an item that would go over, unless nothing is in flight (so one item of any size passes).
pub(crate) struct Budget {
    used: std::sync::Mutex<usize>,
    freed: std::sync::Condvar,
    limit: usize,
}

impl Budget {
    pub(crate) fn new(limit: usize) -> Budget {
        Budget {
            used: std::sync::Mutex::new(0),
            freed: std::sync::Condvar::new(),
            limit,
        }
    }

    pub(crate) fn take(&self, n: usize) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        while *used > 0 && *used + n > self.limit {
            used = self.freed.wait(used).unwrap_or_else(|e| e.into_inner());
        }
        *used += n;
    }

    pub(crate) fn give(&self, n: usize) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        *used = used.saturating_sub(n);
        self.freed.notify_all();
    }

    /// A guard that frees the whole budget when dropped: held by the receiving side, so that
    /// a sender waiting for budget is released when the receiver stops (returns, fails or
    /// panics) and finds the channel closed instead of waiting forever.
    pub(crate) fn release_on_drop(&self) -> impl Drop + '_ {
        struct Release<'a>(&'a Budget);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                self.0.give(usize::MAX);
            }
        }
        Release(self)
    }
}

/// Runs detection over `layers`, calling `sink` for each block in order.
///
/// Reading and parsing run on their own thread, ahead of the geometry, so that the two
/// overlap; the geometry of a batch runs on rayon's pool.
pub fn detect<I, F>(layers: I, opts: &DetectOptions, sink: F) -> io::Result<()>
where
    I: Iterator<Item = io::Result<Layer>> + Send,
    F: FnMut(Detected) -> io::Result<()>,
{
    read_ahead(layers, |rx| detect_batches(rx, opts, sink))
}

/// Runs `layers` on a thread of its own, `READ_AHEAD` items ahead of `work`, which consumes
/// them from the iterator it is given. Reading stops at the first error or when `work`
/// returns.
pub fn read_ahead<I, T, W>(layers: I, work: W) -> io::Result<T>
where
    I: Iterator<Item = io::Result<Layer>> + Send,
    W: FnOnce(&mut dyn Iterator<Item = io::Result<Layer>>) -> io::Result<T>,
{
    let budget = Budget::new(READ_AHEAD_BYTES);
    let budget = &budget;
    std::thread::scope(|s| {
        // Light layers travel in bundles ([`BUNDLE_BYTES`]): one hand-over between the
        // threads per layer cost more than reading a layer of a few strands.
        let (tx, rx) = std::sync::mpsc::sync_channel::<(Vec<io::Result<Layer>>, usize)>(READ_AHEAD);
        s.spawn(move || {
            let mut bundle = Vec::new();
            let mut bundle_w = 0;
            let mut layers = layers.peekable();
            while let Some(l) = layers.next() {
                // A layer spread over metres is refused before any geometry is built on it.
                let l = l.and_then(|l| l.check_span().map(|()| l));
                let failed = l.is_err();
                bundle_w += l.as_ref().map_or(0, weight);
                bundle.push(l);
                // (A heavy layer goes at once, not after the next one is read.)
                if !failed && !bundle_full(bundle.len(), bundle_w) && layers.peek().is_some() {
                    continue;
                }
                budget.take(bundle_w);
                // A closed channel means the work stopped (an error downstream): stop too.
                if tx.send((std::mem::take(&mut bundle), bundle_w)).is_err() || failed {
                    break;
                }
                bundle_w = 0;
            }
        });
        // `rx` is dropped on return, which releases a reader blocked on a full channel; the
        // guard frees the budget so that a reader waiting on it finds the channel closed.
        let _release = budget.release_on_drop();
        let mut it = rx.into_iter().flat_map(|(ls, w)| {
            budget.give(w);
            ls
        });
        work(&mut it)
    })
}

/// A layer read but not yet handed on: whether its area is needed depends on the proof of
/// the layer after it.
struct Pending {
    layer: Layer,
    support: Support,
    /// [`super::proof::supported`] held (or the layer cannot have regions at all).
    proven: bool,
}

fn detect_batches<I, F>(mut layers: I, opts: &DetectOptions, mut sink: F) -> io::Result<()>
where
    I: Iterator<Item = io::Result<Layer>>,
    F: FnMut(Detected) -> io::Result<()>,
{
    // Areas of the last layers handed on (index, area where computed): the last one only,
    // unless layers rest on more than the layer before them (objects of different layer
    // heights interleave); and the support of the last layer handed on.
    let mut hist: VecDeque<(usize, Option<MultiPolygon<f64>>)> = VecDeque::new();
    let mut multi = false;
    // The first layers (on the bed) seen so far, by index.
    let mut on_bed: Vec<usize> = Vec::new();
    let mut below_support: Option<Support> = None;
    // The support material strands of the recent layers that print some (index, strands):
    // a layer found over air where the slicer supported it, across its contact gap
    // ([`Layer::contact`]), looks again with them.
    let mut contact_hist: VecDeque<(usize, Vec<ContactLine>)> = VecDeque::new();
    let mut last: Option<(Strands, MultiPolygon<f64>)> = None;
    // The last layer read is held back until the next one's proof is known.
    let mut window: Vec<Pending> = Vec::with_capacity(BATCH + 1);
    let mut fresh: Vec<Layer> = Vec::with_capacity(BATCH);
    let mut batch_bytes = 0;
    let (mut lines, mut found) = (0u64, 0u64);
    loop {
        let next = layers.next().transpose()?;
        let end = next.is_none();
        if let Some(l) = next {
            batch_bytes += weight(&l);
            fresh.push(l);
        }
        // Light layers (a few strands each) fill a batch by weight, up to [`MAX_BATCH`] of
        // them: a batch's hand-over to the pool costs some ten microseconds whatever it holds.
        let full = (fresh.len() >= BATCH && batch_bytes >= BATCH_MIN_BYTES)
            || fresh.len() >= MAX_BATCH
            || batch_bytes >= BATCH_BYTES;
        if !full && !end {
            continue;
        }
        batch_bytes = 0;
        // From the first layer that rests on more (or other) than the layer before it on,
        // every area is computed and the recent ones kept: such a layer may rest on a layer
        // handed on well before it.
        multi |= fresh
            .iter()
            .any(|l| l.kind == LayerKind::Layer && l.index > 0 && !l.on_bed() && !l.on_previous());
        let supports: Vec<Support> = fresh
            .par_iter()
            .map(|l| {
                if opts.prove && l.kind == LayerKind::Layer {
                    Support::new(l, opts)
                } else {
                    Support::default()
                }
            })
            .collect();
        let first_new = window.len();
        window.extend(
            fresh
                .drain(..)
                .zip(supports)
                .map(|(layer, support)| Pending {
                    layer,
                    support,
                    proven: false,
                }),
        );
        prove_window(&mut window, first_new, below_support.as_ref(), opts);
        // Everything but the held-back layer is handed on (all of it at the end).
        let take = if end { window.len() } else { window.len() - 1 };
        let batch: Vec<Pending> = window.drain(..take).collect();
        // A layer's area is needed when its own proof failed or that of a layer resting on
        // it did (the next one, unless layers interleave).
        let rested_on_unproven = |k: usize| -> bool {
            let i = batch[k].layer.index;
            batch[k + 1..].iter().chain(window.iter()).any(|p| {
                p.layer.kind == LayerKind::Layer && !p.proven && p.layer.rests_on.contains(&i)
            })
        };
        let need: Vec<bool> = (0..batch.len())
            .map(|k| {
                batch[k].layer.kind == LayerKind::Layer
                    && (!batch[k].proven || multi || rested_on_unproven(k))
            })
            .collect();
        let layers_only: Vec<&Layer> = batch.iter().map(|p| &p.layer).collect();
        let areas = batch_areas(&layers_only, &need, &mut last, opts);
        let mut belows = Vec::with_capacity(batch.len());
        let keep = if multi {
            crate::layers::RECENT_LAYERS
        } else {
            1
        };
        for (p, a) in batch.iter().zip(&areas) {
            let below = below_of(&p.layer, &hist);
            // The layer on the first one stands on the first layer squashed out to the
            // outline the slicer drew it in from.
            let on_first = opts.first_layer_shrink > 0.0
                && p.layer.rests_on.iter().any(|i| on_bed.contains(i));
            belows.push(if on_first {
                below.map(|b| super::offset(&b, opts.first_layer_shrink))
            } else {
                below
            });
            if p.layer.on_bed() && on_bed.len() < 16 {
                on_bed.push(p.layer.index);
            }
            if p.layer.kind == LayerKind::Layer {
                if hist.len() >= keep {
                    hist.drain(..=hist.len() - keep);
                }
                hist.push_back((p.layer.index, a.clone()));
            }
        }
        for p in &batch {
            let lines = contact_lines(&p.layer);
            if !lines.is_empty() {
                if contact_hist.len() >= CONTACT_KEEP {
                    contact_hist.pop_front();
                }
                contact_hist.push_back((p.layer.index, lines));
            }
        }
        let searched: Vec<(Vec<Region>, Option<MultiPolygon<f64>>)> = batch
            .par_iter()
            .zip(areas.par_iter())
            .zip(belows.par_iter())
            .map(|((p, a), b)| {
                let l = &p.layer;
                // The first layer rests on the bed.
                if l.kind != LayerKind::Layer || l.on_bed() || p.proven {
                    return (Vec::new(), None);
                }
                match (a, b) {
                    // A layer the polygon library fails on (a panic deep in geo's booleans)
                    // has no regions: it is left as sliced, and the rest of the file is not.
                    (Some(a), Some(b)) => {
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                            let regions = find_regions_as_sliced(b, l, a, opts);
                            if regions.is_empty() || l.contact.is_empty() {
                                return (regions, None);
                            }
                            match with_contact(b, l, &regions, &contact_hist, opts) {
                                Some(b) => (find_regions_as_sliced(&b, l, a, opts), Some(b)),
                                None => (regions, None),
                            }
                        }))
                        .unwrap_or_default()
                    }
                    // Both are computed whenever the proof failed (see `need`), but for a
                    // layer resting on one handed on before layers were seen to interleave:
                    // what it rests on is not known, and it is left as sliced.
                    _ => (Vec::new(), None),
                }
            })
            .collect();
        let mut regions = Vec::with_capacity(searched.len());
        for ((r, b), below) in searched.into_iter().zip(belows.iter_mut()) {
            if b.is_some() {
                *below = b;
            }
            regions.push(r);
        }
        lines += batch
            .iter()
            .map(|p| (p.layer.last_line + 1).saturating_sub(p.layer.first_line))
            .sum::<u64>();
        found += regions.iter().map(|r| r.len() as u64).sum::<u64>();
        check_region_density(found, lines)?;
        for (((p, area), below), regions) in batch.into_iter().zip(areas).zip(belows).zip(regions) {
            if p.layer.kind == LayerKind::Layer {
                below_support = Some(p.support);
            }
            sink(Detected {
                layer: p.layer,
                area,
                below,
                regions,
            })?;
        }
        if end {
            return Ok(());
        }
    }
}

/// Layers with support material whose strands detection keeps: more than the
/// [`crate::layers::CONTACT_GAP`] spans at the finest layer heights.
const CONTACT_KEEP: usize = 12;

/// A support strand: its points and bead width.
type ContactLine = (Vec<[f64; 2]>, f64);

/// The layer's support material strands. Sparse support without an interface (Cura's
/// default, no support roof; its tree support) holds the part too, as the slicer planned it:
/// loops over it bought nothing the deposition check could see, at two minutes a part.
fn contact_lines(layer: &Layer) -> Vec<ContactLine> {
    if layer.kind != LayerKind::Layer {
        return Vec::new();
    }
    layer
        .paths
        .iter()
        .filter(|p| p.role.is_support())
        .map(|p| (p.points.clone(), p.width))
        .collect()
}

/// `below` with the area printed by the support material under `layer` across its contact
/// gap, near `regions` (its boxes grown by a few millimetres); `None` when no such support
/// comes near them.
fn with_contact(
    below: &MultiPolygon<f64>,
    layer: &Layer,
    regions: &[Region],
    hist: &VecDeque<(usize, Vec<ContactLine>)>,
    opts: &DetectOptions,
) -> Option<MultiPolygon<f64>> {
    use geo::BoundingRect;
    const MARGIN: f64 = 3.0;
    let grown = geo::coord! { x: MARGIN, y: MARGIN };
    let boxes: Vec<geo::Rect<f64>> = regions
        .iter()
        .filter_map(|r| r.polygon.bounding_rect())
        .map(|b| geo::Rect::new(b.min() - grown, b.max() + grown))
        .collect();
    let near = |pts: &[[f64; 2]]| {
        super::points_box(pts)
            .is_some_and(|b| boxes.iter().any(|r| super::regions::boxes_meet(&b, r)))
    };
    let lines: Vec<(&[[f64; 2]], f64)> = hist
        .iter()
        .filter(|(i, _)| layer.contact.contains(i))
        .flat_map(|(_, lines)| lines.iter())
        .filter(|(pts, _)| near(pts))
        .map(|(pts, w)| (pts.as_slice(), *w))
        .collect();
    if lines.is_empty() {
        return None;
    }
    let support = super::area::support_area(lines, &opts.area);
    Some(super::union(below, &support))
}

/// The area a layer rests on: the union of the areas of the layers it rests on, from the
/// recent ones in `hist`; `None` when one of them is not there (or its area was not computed).
/// Empty for the preamble and the first layer.
fn below_of(
    layer: &Layer,
    hist: &VecDeque<(usize, Option<MultiPolygon<f64>>)>,
) -> Option<MultiPolygon<f64>> {
    let mut parts = layer.rests_on.iter().map(|i| {
        hist.iter()
            .find(|(j, _)| j == i)
            .and_then(|(_, a)| a.as_ref())
    });
    let Some(first) = parts.next() else {
        return Some(MultiPolygon::new(Vec::new()));
    };
    let mut union = first?.clone();
    for a in parts {
        union = super::union(&union, a?);
    }
    Some(union)
}

/// Runs the proof for the window's layers from `from` on, each against the layer below it
/// (in the window or, for the first, `before`).
fn prove_window(
    window: &mut [Pending],
    from: usize,
    before: Option<&Support>,
    opts: &DetectOptions,
) {
    let mut below_of: Vec<Option<usize>> = Vec::with_capacity(window.len());
    let mut prev: Option<usize> = None;
    for p in window.iter().enumerate() {
        below_of.push(prev);
        if p.1.layer.kind == LayerKind::Layer {
            prev = Some(p.0);
        }
    }
    let proven: Vec<bool> = (from..window.len())
        .into_par_iter()
        .map(|k| {
            let p = &window[k];
            if p.layer.kind != LayerKind::Layer {
                return false;
            }
            if p.layer.on_bed() {
                return true;
            }
            // The proof compares a layer with the one layer before it.
            if !opts.prove || !p.layer.on_previous() {
                return false;
            }
            let below = match below_of[k] {
                Some(j) => Some(&window[j].support),
                None => before,
            };
            below.is_some_and(|b| supported(b, &p.layer, &p.support, opts))
        })
        .collect();
    for (p, v) in window[from..].iter_mut().zip(proven) {
        p.proven = v;
    }
}

/// Regions found before [`check_region_density`] judges their density.
const DENSITY_AFTER: u64 = 500;
/// Fewest lines of G-code per region in a sliced part: a layer with a region over air also
/// prints the part's walls and infill, hundreds of lines. Files with a region every few lines
/// (a million one-move layers) are made to exhaust time and memory, not to be printed.
const MIN_LINES_PER_REGION: u64 = 20;

/// Stops a file whose regions come far denser than any slicer's output.
fn check_region_density(found: u64, lines: u64) -> io::Result<()> {
    if found >= DENSITY_AFTER && found * MIN_LINES_PER_REGION > lines {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "{found} regions over air in {lines} lines (one every {} lines): this is not a sliced part; poa stops here",
                lines / found.max(1)
            ),
        ));
    }
    Ok(())
}

/// Printed areas of the layers of a batch that `need` them (`None` for the others). A wall
/// that rises straight repeats its outline strands exactly, layer after layer; their
/// footprint (the costly buffer) is computed once and reused, the last one carried into the
/// next batch.
fn batch_areas(
    batch: &[&Layer],
    need: &[bool],
    last: &mut Option<(Strands, MultiPolygon<f64>)>,
    opts: &DetectOptions,
) -> Vec<Option<MultiPolygon<f64>>> {
    let strands: Vec<Option<Strands>> = batch
        .par_iter()
        .zip(need.par_iter())
        .map(|(l, &n)| n.then(|| outline_strands(l)))
        .collect();
    // Index of the layer whose footprint each layer shares (itself when fresh); usize::MAX
    // for the footprint carried in from the previous batch.
    let mut source: Vec<Option<usize>> = Vec::with_capacity(batch.len());
    let mut prev: Option<(usize, &Strands)> = last.as_ref().map(|(s, _)| (usize::MAX, s));
    for (i, s) in strands.iter().enumerate() {
        match s {
            None => source.push(None),
            Some(s) => match prev {
                Some((j, p)) if p == s => source.push(Some(j)),
                _ => {
                    source.push(Some(i));
                    prev = Some((i, s));
                }
            },
        }
    }
    let fresh: Vec<Option<MultiPolygon<f64>>> = strands
        .par_iter()
        .enumerate()
        .map(|(i, s)| match s {
            Some(s) if source[i] == Some(i) => Some(s.buffer()),
            _ => None,
        })
        .collect();
    let footprint_of = |i: usize| -> Option<&MultiPolygon<f64>> {
        match source[i]? {
            usize::MAX => last.as_ref().map(|(_, fp)| fp),
            j => fresh[j].as_ref(),
        }
    };
    let areas: Vec<Option<MultiPolygon<f64>>> = batch
        .par_iter()
        .enumerate()
        .map(|(i, l)| footprint_of(i).map(|fp| area_from_footprint(l, fp.clone(), &opts.area)))
        .collect();
    if let Some(i) = source.iter().rposition(Option::is_some) {
        let fp = footprint_of(i).cloned();
        if let (Some(s), Some(fp)) = (strands.into_iter().nth(i).flatten(), fp) {
            *last = Some((s, fp));
        }
    }
    areas
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(index: usize, raw_bytes: usize) -> Layer {
        Layer {
            last_line: 0,
            raw: vec![b';'; raw_bytes],
            ..crate::layers::testing::layer(index, Vec::new())
        }
    }

    #[test]
    fn layers_heavier_than_the_budget_still_arrive_in_order() {
        let big = READ_AHEAD_BYTES + 1;
        let layers = (0..6).map(|i| Ok(layer(i, big)));
        let got: Vec<usize> =
            read_ahead(layers, |it| it.map(|l| l.map(|l| l.index)).collect()).unwrap();
        assert_eq!(got, vec![0, 1, 2, 3, 4, 5]);
    }

    #[test]
    fn work_that_stops_early_releases_a_waiting_reader() {
        let big = READ_AHEAD_BYTES / 2;
        let layers = (0..100).map(|i| Ok(layer(i, big)));
        let first = read_ahead(layers, |it| Ok(it.next().unwrap()?.index)).unwrap();
        assert_eq!(first, 0);
    }

    #[test]
    fn light_layers_travel_in_bundles_and_arrive_all_in_order() {
        // Thousands of layers of a few bytes, with heavy ones among them and an error last:
        // every layer once, in order, the error where it was.
        let n = 5000;
        let layers = (0..=n).map(|i| {
            if i == n {
                Err(io::Error::other("bad"))
            } else {
                Ok(layer(i, if i % 997 == 0 { BUNDLE_BYTES + 1 } else { 20 }))
            }
        });
        let got: Vec<Option<usize>> = read_ahead(layers, |it| {
            Ok(it.map(|l| l.ok().map(|l| l.index)).collect())
        })
        .unwrap();
        let want: Vec<Option<usize>> = (0..n).map(Some).chain([None]).collect();
        assert_eq!(got, want);
        assert!(bundle_full(MAX_BATCH, 0) && bundle_full(1, BUNDLE_BYTES));
        assert!(!bundle_full(MAX_BATCH - 1, BUNDLE_BYTES - 1));
    }

    #[test]
    fn a_read_error_ends_the_stream() {
        let layers = (0..5).map(|i| {
            if i == 2 {
                Err(io::Error::other("bad"))
            } else {
                Ok(layer(i, 10))
            }
        });
        let got: Vec<bool> = read_ahead(layers, |it| Ok(it.map(|l| l.is_ok()).collect())).unwrap();
        assert_eq!(got, vec![true, true, false]);
    }
}
