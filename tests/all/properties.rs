//! Property tests: any input is read without panicking and written back unchanged.

use printonair::gcode::{parse_line, LineReader};
use printonair::layers::{LayerReader, ReaderOptions, SlicerConfig};
use proptest::prelude::*;

fn round_trip(data: &[u8]) {
    let lines: Vec<u8> = LineReader::new(data).flat_map(|l| l.unwrap().raw).collect();
    assert_eq!(lines, data);
    let config = SlicerConfig::parse(data);
    let r = LayerReader::new(
        data,
        ReaderOptions {
            keep_raw: true,
            config,
        },
    );
    let mut raw: Vec<u8> = Vec::new();
    for l in r {
        match l {
            Ok(l) => raw.extend(l.raw),
            // The one refusal such lines can reach: inches after printing began (the rest
            // would print 25.4 times larger). Nothing else may fail.
            Err(e) => {
                assert!(
                    e.to_string().contains("G20 (inches) after printing began"),
                    "{e}"
                );
                return;
            }
        }
    }
    assert_eq!(raw, data);
}

/// Lines that look like G-code, to reach deeper into the interpreter than random bytes do.
fn gcode_line() -> impl Strategy<Value = String> {
    let word = (
        prop::sample::select(vec![
            'G', 'M', 'X', 'Y', 'Z', 'E', 'F', 'I', 'J', 'R', 'S', 'T', 'N',
        ]),
        prop_oneof![
            (-1000.0f64..1000.0).prop_map(|v| format!("{v:.3}")),
            Just("1e308".to_string()),
            Just("-0".to_string()),
            Just(".".to_string()),
            (0u32..120).prop_map(|v| v.to_string()),
        ],
    )
        .prop_map(|(l, n)| format!("{l}{n}"));
    prop_oneof![
        prop::collection::vec(word, 0..6).prop_map(|w| w.join(" ")),
        prop::sample::select(vec![
            ";LAYER_CHANGE",
            ";Z:0.4",
            ";HEIGHT:0.2",
            ";TYPE:External perimeter",
            ";WIDTH:0.45",
            ";LAYER:3",
            "G91",
            "G90",
            "M82",
            "M83",
            "G20",
            "G21",
            "G92 E0",
            "G10",
            "G11",
            "EXCLUDE_OBJECT_START NAME=a",
            "M486 S1",
            "M486 Abox",
            "; printing object x",
            "G2 X1 Y1 R-0.1 E1",
            "G3 X0 Y0 I0 J0 E1",
            "(unbalanced",
            "*255",
            "N1 G1*",
        ])
        .prop_map(String::from),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes(data in prop::collection::vec(any::<u8>(), 0..4096)) {
        round_trip(&data);
        for line in data.split(|&b| b == b'\n') {
            let _ = parse_line(line);
        }
    }

    #[test]
    fn arbitrary_gcode_like(lines in prop::collection::vec(gcode_line(), 0..200), crlf in any::<bool>()) {
        let sep = if crlf { "\r\n" } else { "\n" };
        let text = lines.join(sep);
        round_trip(text.as_bytes());
    }
}
