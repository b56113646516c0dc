//! The per-layer pass seam: what a rewrite feature plugs into.
//!
//! Input: one layer as read (raw bytes, interpreter state at its start, paths) with what
//! region detection found in it (nothing, for passes run without detection). Output: the
//! bytes that replace the layer, or `None` to copy it as read.
//!
//! Invariants: a pass returns the layer's own lines byte for byte except where it edits
//! (splice: replaced lines and inserted blocks); it keeps whatever state it needs across
//! layers itself, and its report is its own. Print-on-Air ([`crate::emit::PoaPass`]) and the
//! A/B copy ([`crate::ab::AbPass`]) are the first two.

use crate::error::Error;
use crate::geometry::Detected;

pub trait Pass {
    /// The layer's new bytes, or `None` to leave it as it is.
    fn layer(&mut self, found: &Detected) -> Result<Option<Vec<u8>>, Error>;
}
