//! The link to Debian's PT-Scotch (`libptscotch-dev`). Its default library, the one in
//! the plain library directory, numbers vertices with a C `int`, which `src/lib.rs`
//! declares as `i32`; `scotch_num_is_32_bits` in the tests checks that at run time.

fn main() {
    println!("cargo:rustc-link-lib=ptscotch");
    println!("cargo:rustc-link-lib=ptscotcherr");
    println!("cargo:rustc-link-lib=scotch");
}
