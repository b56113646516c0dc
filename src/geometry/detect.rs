//! Region detection over a stream of layers.
//!
//! Input: an iterator of [`Layer`]s. Output: for each block in file order, a [`Detected`] with
//! the layer, its printed area, the printed area below it and its unsupported regions, handed
//! to a callback. Layers are processed in small batches whose geometry runs on all cores;
//! only a batch and the area of the layer before it are held at once.

use std::io;

use geo::MultiPolygon;
use rayon::prelude::*;

use crate::layers::{Layer, LayerKind};

use super::{find_regions, printed_area, DetectOptions, Region};

/// Layers per parallel batch: enough to keep two cores busy, few enough to keep memory flat
/// (a layer of a big plate holds megabytes of strands).
const BATCH: usize = 4;

/// One block of the file with what detection found.
pub struct Detected {
    pub layer: Layer,
    /// Printed area of this layer (empty for the preamble).
    pub area: MultiPolygon<f64>,
    /// Printed area of the layer below (empty for the first layer and the preamble).
    pub below: MultiPolygon<f64>,
    pub regions: Vec<Region>,
}

/// Layers read ahead of the geometry: the next batch, read while one is computed.
const READ_AHEAD: usize = BATCH;

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
    std::thread::scope(|s| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<io::Result<Layer>>(READ_AHEAD);
        s.spawn(move || {
            for l in layers {
                let failed = l.is_err();
                // A closed channel means the work stopped (an error downstream): stop too.
                if tx.send(l).is_err() || failed {
                    break;
                }
            }
        });
        // `rx` is dropped on return, which releases a reader blocked on a full channel.
        let mut it = rx.into_iter();
        work(&mut it)
    })
}

fn detect_batches<I, F>(layers: I, opts: &DetectOptions, mut sink: F) -> io::Result<()>
where
    I: Iterator<Item = io::Result<Layer>>,
    F: FnMut(Detected) -> io::Result<()>,
{
    let mut below = MultiPolygon::new(Vec::new());
    let mut batch: Vec<Layer> = Vec::with_capacity(BATCH);
    let mut layers = layers.peekable();
    loop {
        let next = layers.next().transpose()?;
        let end = next.is_none();
        if let Some(l) = next {
            batch.push(l);
        }
        if batch.len() < BATCH && !end {
            continue;
        }
        let areas: Vec<MultiPolygon<f64>> = batch
            .par_iter()
            .map(|l| match l.kind {
                LayerKind::Layer => printed_area(l, &opts.area),
                LayerKind::Preamble => MultiPolygon::new(Vec::new()),
            })
            .collect();
        let mut belows = Vec::with_capacity(batch.len());
        for (l, a) in batch.iter().zip(&areas) {
            belows.push(below.clone());
            if l.kind == LayerKind::Layer {
                below = a.clone();
            }
        }
        let regions: Vec<Vec<Region>> = batch
            .par_iter()
            .zip(areas.par_iter())
            .zip(belows.par_iter())
            .map(|((l, a), b)| {
                // The first layer rests on the bed.
                if l.kind == LayerKind::Layer && l.index > 0 {
                    find_regions(b, l, a, opts)
                } else {
                    Vec::new()
                }
            })
            .collect();
        for (((layer, area), below), regions) in batch.drain(..).zip(areas).zip(belows).zip(regions)
        {
            sink(Detected {
                layer,
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
