//! Bindings to MUMPS's C interface (`dmumps_c.h`) by bindgen, and the link to Debian's
//! libdmumps. The communicator crosses as a Fortran handle (an int), so no MPI header
//! is needed here.

fn main() {
    println!("cargo:rerun-if-changed=wrapper.h");
    println!("cargo:rustc-link-lib=dmumps");
    println!("cargo:rustc-link-lib=mumps_common");
    let bindings = bindgen::Builder::default()
        .header("wrapper.h")
        .allowlist_type("DMUMPS_STRUC_C")
        .allowlist_function("dmumps_c")
        .derive_default(false)
        .generate()
        .unwrap_or_else(|e| {
            panic!("bindgen on dmumps_c.h failed ({e}); install Debian's libmumps-dev (run-scripts/setup.sh --deps)")
        });
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR").unwrap());
    bindings
        .write_to_file(out.join("bindings.rs"))
        .expect("write the MUMPS bindings");
}
