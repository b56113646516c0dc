//! The lossless reader and the layer model: any bytes, written back unchanged.
#![no_main]

use libfuzzer_sys::fuzz_target;
use printonair::gcode::{parse_line, LineReader};
use printonair::layers::{LayerReader, ReaderOptions, SlicerConfig};

fuzz_target!(|data: &[u8]| {
    let lines: Vec<u8> = LineReader::new(data).flat_map(|l| l.unwrap().raw).collect();
    assert_eq!(lines, data);
    for line in data.split(|&b| b == b'\n') {
        let _ = parse_line(line);
    }
    let config = SlicerConfig::parse(data);
    let raw: Vec<u8> = LayerReader::new(data, ReaderOptions { keep_raw: true, config })
        .flat_map(|l| l.unwrap().raw)
        .collect();
    assert_eq!(raw, data);
});
