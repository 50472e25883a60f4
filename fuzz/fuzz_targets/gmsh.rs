//! Any bytes through the Gmsh reader: a mesh or one input error of one line naming the
//! file, never a panic (an index, an overflow, a huge allocation).
#![no_main]

use contact_par::error::Error;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match contact_par::mesh::gmsh::parse_msh(data, "fuzz.msh") {
        Ok(_) => {}
        Err(Error::Input(msg)) => {
            assert!(msg.starts_with("fuzz.msh") && !msg.contains('\n'), "{msg}");
        }
        Err(e) => panic!("not an input error: {e:?}"),
    }
});
