//! Binary G-code decoding: errors, never panics; what decodes re-encodes and decodes again.
#![no_main]

use libfuzzer_sys::fuzz_target;
use printonair::bgcode;

fuzz_target!(|data: &[u8]| {
    if let Ok(b) = bgcode::decode(data) {
        let _ = b.to_ascii();
        let again = bgcode::encode(&b);
        assert!(bgcode::decode(&again).is_ok());
    }
});
