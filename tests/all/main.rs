//! poa's integration tests: one test binary, a module per topic (as ripgrep keeps its own).
//! Tests that need a slicer, libbgcode's Python wrapper or the team's `../shared` folder skip
//! with a printed note when it is absent (except under `CI`, where the slicer and the wrapper
//! must be there); see `common`.

mod common;

mod ab;
mod bgcode;
mod bgcode_rewrite;
mod cli;
mod compare_page;
mod cura_parts;
mod cura_script;
mod deform;
mod estimate;
mod faults;
mod fiveaxis;
mod frontend;
mod golden;
mod parts;
mod proof;
mod properties;
mod real_parts;
mod regions;
mod rewrite;
mod safety;
mod slicer_mode;
mod texture;
