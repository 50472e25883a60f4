//! Any text through the case-file parser and its checks: a case or one input error of one
//! line naming the file, never a panic.
#![no_main]

use contact_par::error::Error;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // The binary reads case files as UTF-8 and refuses anything else before parsing.
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match contact_par::case::parse_case(text, "fuzz.toml", Path::new(".")) {
        Ok(_) => {}
        Err(Error::Input(msg)) => {
            assert!(msg.starts_with("fuzz.toml") && !msg.contains('\n'), "{msg}");
        }
        Err(e) => panic!("not an input error: {e:?}"),
    }
});
