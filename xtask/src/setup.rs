//! What every job shares: the repository's root, running commands, and installing what a
//! fresh Debian machine lacks (Debian packages, the pinned Python venv, cargo-zigbuild),
//! the portable (glibc 2.17) build, and the stamps that let an unchanged re-run skip work.

/// What a job and its builders return: the error is the message a user reads.
pub(crate) type Result<T = ()> = std::result::Result<T, String>;

/// The FMU's model identifier: the names of its library and archives.
pub(crate) const MODEL_IDENTIFIER: &str = "CyclicMechanism";

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

pub(crate) fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

pub(crate) fn run(command: &mut Command) -> Result {
    let shown = format!("{command:?}");
    let status = command
        .status()
        .map_err(|e| format!("cannot start {shown}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{shown} failed ({status})"))
    }
}

/// What `command` prints on standard output; its standard error in the message when it
/// fails.
pub(crate) fn output_of(command: &mut Command) -> Result<String> {
    let shown = format!("{command:?}");
    let output = command
        .output()
        .map_err(|e| format!("cannot run {shown}: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "{shown} failed: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

/// A path that a line of Python run by the venv's `python` prints.
pub(crate) fn python_path(python: &Path, code: &str) -> Result<PathBuf> {
    let printed = output_of(Command::new(python).args(["-c", code]))?;
    Ok(PathBuf::from(printed.trim()))
}

pub(crate) fn cargo() -> Command {
    let mut command = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    command.current_dir(root());
    command
}

/// A test build of the release profile without link-time optimisation and with parallel
/// code generation: each test binary would otherwise be linked with a whole-program LTO
/// of its own, minutes of a suite's time on two cores. The numbers do not change (Rust
/// does not reorder or fuse floating-point operations under any optimisation), and the
/// FMU that the masters and the Python suite test is built with the full profile.
pub(crate) fn as_test_build(command: &mut Command) -> &mut Command {
    command
        .env("CARGO_PROFILE_RELEASE_LTO", "off")
        .env("CARGO_PROFILE_RELEASE_CODEGEN_UNITS", "16")
}

/// libclang (for bindgen in fmi-sys): install Debian's libclang-dev when it is missing.
pub(crate) fn ensure_libclang() -> Result {
    let dirs = [
        "/usr/lib",
        "/usr/lib/x86_64-linux-gnu",
        "/usr/lib/aarch64-linux-gnu",
    ];
    let llvm_libs = fs::read_dir("/usr/lib")
        .into_iter()
        .flat_map(|entries| entries.flatten())
        .filter(|entry| entry.file_name().to_string_lossy().starts_with("llvm-"))
        .map(|entry| entry.path().join("lib"));
    let found = dirs
        .iter()
        .map(PathBuf::from)
        .chain(llvm_libs)
        .filter_map(|dir| fs::read_dir(dir).ok())
        .flat_map(|entries| entries.flatten())
        .any(|entry| is_libclang(&entry.file_name().to_string_lossy()));
    if found || std::env::var_os("LIBCLANG_PATH").is_some() {
        return Ok(());
    }
    println!("xtask: installing libclang-dev (needed by bindgen for the FMI headers)");
    apt_install(&["libclang-dev"])
}

/// `libclang.so*` or `libclang-<version>.so*`, the names bindgen loads; not libclang-cpp.
pub(crate) fn is_libclang(name: &str) -> bool {
    name.strip_prefix("libclang").is_some_and(|rest| {
        rest.starts_with(".so")
            || rest
                .strip_prefix('-')
                .is_some_and(|v| v.starts_with(|c: char| c.is_ascii_digit()))
    })
}

/// Debian's Chromium, in which the report tests and benchmark open the reports, headless.
pub(crate) fn ensure_chromium() -> Result {
    if Command::new("chromium").arg("--version").output().is_err() {
        println!("xtask: installing chromium");
        apt_install(&["chromium"])?;
    }
    Ok(())
}

pub(crate) fn apt_install(packages: &[&str]) -> Result {
    run(Command::new("apt-get").args(["update", "-qq"]))?;
    run(Command::new("apt-get")
        .args(["install", "-y", "-qq"])
        .args(packages)
        .env("DEBIAN_FRONTEND", "noninteractive"))
}

/// What the Python venv must hold: the demo's packages (also the FMU's build, for zig), or
/// those and the tests'.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Packages {
    Demo,
    Tests,
}

/// The Python venv `target/venv` with the pinned packages of `tests/python/requirements-demo.txt`
/// (and of `requirements.txt` for [`Packages::Tests`]); added to or rebuilt when the pins
/// change. The demo's set is a subset of the tests', so one venv serves both.
pub(crate) fn ensure_venv(packages: Packages) -> Result<PathBuf> {
    let root = root();
    let venv = root.join("target/venv");
    let python = venv.join("bin/python");
    let read = |name: &str| {
        let path = root.join("tests/python").join(name);
        fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))
    };
    let demo = format!("demo\n{}", read("requirements-demo.txt")?);
    let tests = format!("{demo}tests\n{}", read("requirements.txt")?);
    let stamp = venv.join("requirements.installed");
    let installed = fs::read_to_string(&stamp).unwrap_or_default();
    let (wanted, file) = match packages {
        Packages::Demo => (&demo, "requirements-demo.txt"),
        Packages::Tests => (&tests, "requirements.txt"),
    };
    if python.exists() && (installed == *wanted || installed == tests) {
        return Ok(python);
    }
    if !(python.exists() && installed == demo) {
        println!("xtask: creating the Python venv in {}", venv.display());
        if run(Command::new("python3")
            .args(["-m", "venv", "--clear"])
            .arg(&venv))
        .is_err()
        {
            apt_install(&["python3-venv"])?;
            run(Command::new("python3")
                .args(["-m", "venv", "--clear"])
                .arg(&venv))?;
        }
    }
    println!("xtask: installing the pinned packages of tests/python/{file}");
    run(pip_install(&python)
        .arg("-r")
        .arg(root.join("tests/python").join(file)))?;
    fs::write(&stamp, wanted).map_err(|e| e.to_string())?;
    Ok(python)
}

pub(crate) fn pip_install(python: &Path) -> Command {
    let mut command = Command::new(python);
    command.args([
        "-m",
        "pip",
        "install",
        "--quiet",
        "--disable-pip-version-check",
    ]);
    command
}

/// The oldest glibc the packed binary may need: RHEL/CentOS 7 and every later Linux.
pub(crate) const GLIBC_BASELINE: (u32, u32) = (2, 17);

pub(crate) const ZIGBUILD_VERSION: &str = "0.24.1";

/// Build `artifact` (in release) against glibc 2.17 with cargo-zigbuild and the zig of the
/// pinned `ziglang` Python package.
pub(crate) fn build_portable(selection: &[&str], artifact: &str) -> Result<PathBuf> {
    let python = ensure_venv(Packages::Demo)?;
    let has_zigbuild = cargo()
        .args(["zigbuild", "--help"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_zigbuild {
        println!(
            "xtask: installing cargo-zigbuild {ZIGBUILD_VERSION} (builds against an old glibc)"
        );
        run(cargo().args([
            "install",
            "--quiet",
            "--locked",
            "cargo-zigbuild",
            "--version",
            ZIGBUILD_VERSION,
        ]))?;
    }
    let path = path_with_venv(&python)?;
    let target = "x86_64-unknown-linux-gnu";
    run(cargo()
        .args(["zigbuild", "--release"])
        .args(selection)
        .args([
            "--target",
            &format!("{target}.{}.{}", GLIBC_BASELINE.0, GLIBC_BASELINE.1),
        ])
        .env("PATH", path)
        // cargo-zigbuild hands bindgen `-nostdinc` and zig's include paths, which it cannot
        // collect for a versioned glibc triple with this zig; the FMI headers need only the
        // standard C headers, the same for any glibc version.
        .env("BINDGEN_EXTRA_CLANG_ARGS", c_header_args()?))?;
    Ok(root().join(format!("target/{target}/release/{artifact}")))
}

/// PATH with the venv's bin first: its `python` (with the pinned zig) and its tools.
pub(crate) fn path_with_venv(python: &Path) -> Result<std::ffi::OsString> {
    let venv_bin = python.parent().expect("the venv's bin").to_path_buf();
    std::env::join_paths(std::iter::once(venv_bin).chain(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    )))
    .map_err(|e| e.to_string())
}

/// `-isystem` for clang's own headers and the system's C headers.
pub(crate) fn c_header_args() -> Result<String> {
    Ok(format!(
        "-isystem {} -isystem /usr/include/x86_64-linux-gnu -isystem /usr/include",
        clang_include_dir()?.display()
    ))
}

/// Clang's own headers (stddef.h, mm_malloc.h, …), of libclang-dev.
pub(crate) fn clang_include_dir() -> Result<PathBuf> {
    fs::read_dir("/usr/lib")
        .into_iter()
        .flat_map(|entries| entries.flatten())
        .filter(|e| e.file_name().to_string_lossy().starts_with("llvm-"))
        .flat_map(|e| {
            fs::read_dir(e.path().join("lib/clang"))
                .into_iter()
                .flat_map(|d| d.flatten())
        })
        .map(|version| version.path().join("include"))
        .find(|include| include.join("stddef.h").exists())
        .ok_or_else(|| {
            "clang's stddef.h not found under /usr/lib/llvm-*/lib/clang (libclang-dev)".into()
        })
}

/// The highest `GLIBC_x.y` symbol version the library needs, from `objdump -T`, must not
/// pass the baseline.
pub(crate) fn check_glibc(library: &Path) -> Result {
    let text = output_of(Command::new("objdump").arg("-T").arg(library))?;
    let newest = text
        .split("GLIBC_")
        .skip(1)
        .filter_map(|rest| {
            let version: String = rest
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '.')
                .collect();
            let mut parts = version.split('.').map(|p| p.parse::<u32>().unwrap_or(0));
            Some((parts.next()?, parts.next().unwrap_or(0)))
        })
        .max()
        .ok_or_else(|| format!("{}: no GLIBC symbol versions found", library.display()))?;
    if newest > GLIBC_BASELINE {
        return Err(format!(
            "{} needs GLIBC_{}.{}, above the {}.{} baseline",
            library.display(),
            newest.0,
            newest.1,
            GLIBC_BASELINE.0,
            GLIBC_BASELINE.1
        ));
    }
    Ok(())
}

/// Run `check` unless it passed before on inputs of exactly these bytes (a fingerprint of
/// their names and contents in `target/passed/`): an unchanged re-run skips it, saying so.
pub(crate) fn unless_passed_before(
    name: &str,
    inputs: &[PathBuf],
    check: impl FnOnce() -> Result,
) -> Result {
    let stamp = root().join("target/passed").join(name.replace(' ', "_"));
    let key = fingerprint(inputs)?;
    if fs::read_to_string(&stamp).is_ok_and(|passed| passed == key) {
        println!("xtask: {name}: passed before on these very files (fingerprint {key}), skipped");
        return Ok(());
    }
    check()?;
    fs::create_dir_all(root().join("target/passed")).map_err(|e| e.to_string())?;
    fs::write(&stamp, key).map_err(|e| e.to_string())
}

/// FNV-1a (64 bits) over each file's path and bytes, in the given order.
pub(crate) fn fingerprint(paths: &[PathBuf]) -> Result<String> {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for path in paths {
        let bytes = fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let name = path.to_string_lossy();
        for byte in name.bytes().chain([0]).chain(bytes) {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    Ok(format!("{hash:016x}"))
}

/// Every file below `dir`, sorted, but for caches (`__pycache__`, `target`) and hidden ones.
pub(crate) fn files_below(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let entries = fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || name == "__pycache__" || name == "target" {
            continue;
        }
        if path.is_dir() {
            files.extend(files_below(&path)?);
        } else {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// The files of `dir` (not its subdirectories) whose names end in `.ext`, sorted.
pub(crate) fn files_with_extension(dir: &Path, ext: &str) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    Ok(files)
}
