//! Any bytes as the mesh of a fixed, sound case, through the reader and every check of
//! `problem::build` (duplicates, unused nodes, orientation and folds, groups, boundary,
//! gaps, rigid motions): a problem or one input error, never a panic.
#![no_main]

use contact_par::case::{parse_case, Case};
use contact_par::error::Error;
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use std::sync::OnceLock;

/// The baseline case of the bad-input corpus (groups "top", "bottom", "corner").
const CASE: &str = include_str!("../../tests/bad-inputs/_good/case.toml");

fn case() -> &'static Case {
    static CASE_: OnceLock<Case> = OnceLock::new();
    CASE_.get_or_init(|| parse_case(CASE, "fuzz.toml", Path::new(".")).unwrap())
}

fuzz_target!(|data: &[u8]| {
    let result = contact_par::mesh::gmsh::parse_msh(data, "fuzz.msh")
        .and_then(|mesh| contact_par::problem::build(case(), mesh, "fuzz.msh"));
    match result {
        Ok(_) => {}
        Err(Error::Input(msg)) => {
            assert!(msg.starts_with("fuzz.") && !msg.contains('\n'), "{msg}");
        }
        Err(e) => panic!("not an input error: {e:?}"),
    }
});
