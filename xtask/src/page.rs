//! The page's builders: the crate `web/` built for wasm32 (Debian's Rust builds the standard
//! library from its sources, LLVM's wasm-ld links) and the page of `web/page/` around it,
//! written to `target/web/`: static files that a file URL or any web server serves. The
//! module is inlined in a script as base64, because browsers do not fetch files from a
//! file URL. Node, which runs the module against linux64 in the platform tests.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::platforms::{self, DEBIAN_CARGO, DEBIAN_RUSTC, LLVM_BIN};
use crate::setup::Result;
use crate::setup::{apt_install, root, run};

/// The Debian package of the wasm32 build beside Debian's Rust: LLVM's linker.
pub const WASM_PACKAGES: &[(&str, &str)] = &[("lld-14", "1:14.0.6-12")];

const WASM_TARGET: &str = "wasm32-unknown-unknown";

/// The page's own files, copied as they are.
const PAGE_FILES: &[&str] = &["index.html", "style.css", "page.js"];

/// The page in `target/web/`; returns its `index.html`.
pub(crate) fn build_page() -> Result<PathBuf> {
    let wasm = build_wasm()?;
    let out = root().join("target/web");
    fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    for name in PAGE_FILES {
        let from = root().join("web/page").join(name);
        fs::copy(&from, out.join(name)).map_err(|e| format!("{}: {e}", from.display()))?;
    }
    let bytes = fs::read(&wasm).map_err(|e| format!("{}: {e}", wasm.display()))?;
    let script = format!(
        "// The mechanism's WebAssembly module (web/ built for wasm32), as base64.\n\
         const MECHANISM_WASM = \"{}\";\n",
        base64(&bytes)
    );
    let module = out.join("mechanism.js");
    fs::write(&module, script).map_err(|e| format!("{}: {e}", module.display()))?;
    Ok(out.join("index.html"))
}

/// The module `web/` built for wasm32, at its size: no panic unwinding (a panic traps).
pub(crate) fn build_wasm() -> Result<PathBuf> {
    platforms::ensure_packages(platforms::RUST_PACKAGES)?;
    platforms::ensure_packages(WASM_PACKAGES)?;
    let target_dir = platforms::cross_target_dir().join(WASM_TARGET);
    let cwd = platforms::cross_target_dir();
    fs::create_dir_all(&cwd).map_err(|e| format!("{}: {e}", cwd.display()))?;
    println!("xtask: building the page's WebAssembly module (wasm32, Debian's rustc)");
    run(Command::new(DEBIAN_CARGO)
        .current_dir(&cwd)
        .args(["build", "--manifest-path"])
        .arg(root().join("Cargo.toml"))
        .args([
            "--release",
            "--quiet",
            "--package",
            "mechanism-web",
            "--lib",
        ])
        .args(["--target", WASM_TARGET, "-Zbuild-std=std,panic_abort"])
        .env("RUSTC", DEBIAN_RUSTC)
        .env("RUSTC_BOOTSTRAP", "1")
        .env("CARGO_TARGET_DIR", &target_dir)
        .env("CARGO_PROFILE_RELEASE_PANIC", "abort")
        // 128-bit SIMD, which every browser of the last years runs: the integrator's stage
        // sums in pairs of f64, as the native build's vector copy has them.
        .env(
            "CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS",
            "-C target-feature=+simd128",
        )
        .env(
            "CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_LINKER",
            Path::new(LLVM_BIN).join("wasm-ld"),
        )
        .env_remove("CARGO")
        .env_remove("RUSTUP_TOOLCHAIN")
        .env_remove("CARGO_MANIFEST_DIR"))?;
    let wasm = target_dir
        .join(WASM_TARGET)
        .join("release/mechanism_web.wasm");
    if !wasm.exists() {
        return Err(format!("the build left no {}", wasm.display()));
    }
    Ok(wasm)
}

/// Node, which runs the module against linux64 in the tests: Debian's, where none is.
pub(crate) fn ensure_node() -> Result<PathBuf> {
    if Command::new("node").arg("--version").output().is_err() {
        println!("xtask: installing nodejs");
        apt_install(&["nodejs"])?;
    }
    Ok(PathBuf::from("node"))
}

/// Standard base64 with padding.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::base64;

    #[test]
    fn base64_pads_as_the_standard_does() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }
}
