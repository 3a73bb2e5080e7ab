//! Restrict the shared library's exported symbols to the FMI functions (on Linux; the
//! cross builds' checks in xtask/src/platforms.rs say what the other linkers add), and give
//! the macOS library its packed name.
fn main() {
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    // Without the FMI interfaces (the WebAssembly build's dependency) there is nothing to
    // export and no fmi-sys helper to hide.
    let fmi = std::env::var_os("CARGO_FEATURE_FMI").is_some();
    if os == "linux" && fmi {
        let map = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/exports.map");
        println!(
            "cargo:rustc-cdylib-link-arg=-Wl,--version-script={}",
            map.display()
        );
        println!("cargo:rerun-if-changed=src/exports.map");
    } else if os == "windows" {
        // No time of day in the DLL's header: the same sources give the same bytes.
        println!("cargo:rustc-cdylib-link-arg=-Wl,--no-insert-timestamp");
    } else if os == "macos" {
        // The name the library is known by once packed, rather than the build folder's.
        println!("cargo:rustc-cdylib-link-arg=-Wl,-install_name,@rpath/CyclicMechanism.dylib");
    }
}
