//! Binary G-code both ways: decoding errors, never panics, and what decodes re-encodes and
//! decodes again; any text either converts to binary G-code that decodes, or is refused.
#![no_main]

use libfuzzer_sys::fuzz_target;
use printonair::bgcode;

fuzz_target!(|data: &[u8]| {
    if let Ok(b) = bgcode::decode(data) {
        let text = b.to_ascii();
        let again = bgcode::encode(&b);
        assert!(bgcode::decode(&again).is_ok());
        if let Ok(t) = bgcode::from_ascii(&text, &bgcode::BinarizeConfig::of(&b)) {
            assert!(bgcode::decode(&bgcode::encode(&t)).is_ok());
        }
    } else if let Ok(t) = bgcode::from_ascii(data, &bgcode::BinarizeConfig::prusaslicer()) {
        assert!(bgcode::decode(&bgcode::encode(&t)).is_ok());
    }
});
