//! Project tasks: `cargo xtask <fmu|demo|test|bench|sweep|wheel|bench-sweep>`.
//!
//! Each task installs what it needs on a fresh Debian machine: libclang for the FMI
//! bindings (bindgen), and a Python venv in `target/venv` with the pinned packages of
//! `tests/python/requirements.txt`. This crate deliberately does not depend on the FMU
//! crate: building that needs libclang, which this program installs first.

mod abi_tests;
mod instructions;
mod platforms;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

type Result<T = ()> = std::result::Result<T, String>;

const MODEL_IDENTIFIER: &str = "CyclicMechanism";

fn main() {
    let task = std::env::args().nth(1).unwrap_or_default();
    let rest: Vec<String> = std::env::args().skip(2).collect();
    let result = match task.as_str() {
        "fmu" => fmu_task(&rest),
        "demo" => demo(),
        "test" => test(),
        "test-platforms" => test_platforms().map(drop),
        "bench" => bench(std::env::args().any(|a| a == "--quick")),
        "sweep" => sweep(&rest),
        "wheel" => build_wheel().map(|wheel| println!("wheel: {}", wheel.display())),
        "bench-sweep" => bench_sweep(&rest),
        "instructions" => instructions::measure(),
        _ => Err(USAGE.to_string()),
    };
    if let Err(message) = result {
        eprintln!("xtask {task}: {message}");
        std::process::exit(1);
    }
}

const USAGE: &str = "usage: cargo xtask <task>
  fmu          build and pack target/fmu/CyclicMechanism.fmu (linux64)
               --all-platforms: win64 and darwin64 too, cross-built here (Debian's packages)
  demo         run the paper's two cases through FMPy: CSV, plots and an animation in target/demo
  test         run every test: cargo test, then the FMPy and sweep tests in tests/python
  test-platforms  the win64, darwin64 and aarch64 builds and their tests alone (part of test)
  bench        the work-precision benchmark into target/bench (--quick: a small subset)
  sweep SPEC   run a sweep: SPEC.toml [--workers N] [--scheduler ADDRESS] [--out DIR] [--resume]
               (the packed FMU unless the spec names another)
  wheel        build the fmusweep wheel (the sweep package with its native runner) in target/wheels
  bench-sweep  the sweep benchmark into target/bench-sweep (--quick: a small subset)
  instructions instructions per communication point (callgrind) into docs/bench/instructions.md";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

fn run(command: &mut Command) -> Result {
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
fn output_of(command: &mut Command) -> Result<String> {
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
fn python_path(python: &Path, code: &str) -> Result<PathBuf> {
    let printed = output_of(Command::new(python).args(["-c", code]))?;
    Ok(PathBuf::from(printed.trim()))
}

fn cargo() -> Command {
    let mut command = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    command.current_dir(root());
    command
}

/// libclang (for bindgen in fmi-sys): install Debian's libclang-dev when it is missing.
fn ensure_libclang() -> Result {
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
fn is_libclang(name: &str) -> bool {
    name.strip_prefix("libclang").is_some_and(|rest| {
        rest.starts_with(".so")
            || rest
                .strip_prefix('-')
                .is_some_and(|v| v.starts_with(|c: char| c.is_ascii_digit()))
    })
}

fn apt_install(packages: &[&str]) -> Result {
    run(Command::new("apt-get").args(["update", "-qq"]))?;
    run(Command::new("apt-get")
        .args(["install", "-y", "-qq"])
        .args(packages)
        .env("DEBIAN_FRONTEND", "noninteractive"))
}

/// What the Python venv must hold: the demo's packages (also the FMU's build, for zig), or
/// those and the tests'.
#[derive(Clone, Copy, PartialEq)]
enum Packages {
    Demo,
    Tests,
}

/// The Python venv `target/venv` with the pinned packages of `tests/python/requirements-demo.txt`
/// (and of `requirements.txt` for [`Packages::Tests`]); added to or rebuilt when the pins
/// change. The demo's set is a subset of the tests', so one venv serves both.
fn ensure_venv(packages: Packages) -> Result<PathBuf> {
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

fn pip_install(python: &Path) -> Command {
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
const GLIBC_BASELINE: (u32, u32) = (2, 17);
const ZIGBUILD_VERSION: &str = "0.24.1";

/// The library for `binaries/linux64`, built against glibc 2.17 so that it loads on older
/// Linux (RHEL 7–9, Ubuntu 18.04+), where many industrial FMI tools run.
fn build_portable_library() -> Result<PathBuf> {
    let library = build_portable(
        &["--package", "cyclic-mechanism", "--lib"],
        "libcyclic_mechanism.so",
    )?;
    check_glibc(&library)?;
    Ok(library)
}

/// Build `artifact` (in release) against glibc 2.17 with cargo-zigbuild and the zig of the
/// pinned `ziglang` Python package.
fn build_portable(selection: &[&str], artifact: &str) -> Result<PathBuf> {
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
    let venv_bin = python.parent().expect("the venv's bin").to_path_buf();
    let path = std::env::join_paths(std::iter::once(venv_bin).chain(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    )))
    .map_err(|e| e.to_string())?;
    let target = "x86_64-unknown-linux-gnu";
    run(cargo()
        .args(["zigbuild", "--release", "--quiet"])
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

/// `-isystem` for clang's own headers and the system's C headers.
fn c_header_args() -> Result<String> {
    Ok(format!(
        "-isystem {} -isystem /usr/include/x86_64-linux-gnu -isystem /usr/include",
        clang_include_dir()?.display()
    ))
}

/// Clang's own headers (stddef.h, mm_malloc.h, …), of libclang-dev.
fn clang_include_dir() -> Result<PathBuf> {
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
fn check_glibc(library: &Path) -> Result {
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
    println!(
        "xtask: {} needs glibc {}.{} at most (baseline {}.{})",
        library.display(),
        newest.0,
        newest.1,
        GLIBC_BASELINE.0,
        GLIBC_BASELINE.1
    );
    Ok(())
}

/// Where the cross-built binaries are put, checked, under their platform folders.
const PLATFORM_BINARIES: &str = "target/fmu/platforms";

/// `cargo xtask fmu [--all-platforms]`.
fn fmu_task(args: &[String]) -> Result {
    let all = match args {
        [] => false,
        [flag] if flag == "--all-platforms" => true,
        _ => return Err(format!("unknown arguments {args:?}\n{USAGE}")),
    };
    let packed = build_fmu(all)?;
    for line in &packed.report {
        println!("xtask: {line}");
    }
    println!("FMU: {}", packed.fmu.display());
    Ok(())
}

/// A packed FMU: the archive, the linux64 library in it, and the cross builds' checks.
struct Packed {
    fmu: PathBuf,
    linux64: PathBuf,
    report: Vec<String>,
}

/// Build the library (against the glibc baseline), generate the model description and
/// documentation from the variable table, and pack `target/fmu/CyclicMechanism.fmu`; with
/// `all_platforms`, the win64 and darwin64 binaries too (and aarch64 Linux's, for the
/// tests). Every binary is checked first: a failed check writes no archive.
fn build_fmu(all_platforms: bool) -> Result<Packed> {
    ensure_libclang()?;
    let root = root();
    let library = build_portable_library()?;
    let assets = root.join("target/fmu/assets");
    // Without `--package`: features are then unified over the default members, as for
    // `cargo test`. With it they differ, and the library's cdylib (whose file name carries
    // no hash) would be rebuilt by each in turn, changed or not.
    run(cargo()
        .args(["run", "--release", "--quiet", "--bin", "fmu-assets", "--"])
        .arg(&assets))?;
    let fmu = root.join(format!("target/fmu/{MODEL_IDENTIFIER}.fmu"));
    let mut files = vec![
        (
            "modelDescription.xml".to_string(),
            assets.join("modelDescription.xml"),
        ),
        (
            format!("binaries/linux64/{MODEL_IDENTIFIER}.so"),
            library.clone(),
        ),
        (
            "documentation/index.html".to_string(),
            assets.join("index.html"),
        ),
    ];
    let mut report = vec![format!(
        "linux64 {}: {} bytes",
        library.display(),
        platforms::size(&library)?
    )];
    if all_platforms {
        let zig = platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
        let (binaries, checks) = platforms::build_all(&zig, &root.join(PLATFORM_BINARIES))?;
        files.extend(binaries);
        report.extend(checks);
    }
    pack(&fmu, &files)?;
    report.push(format!(
        "{}: {} bytes",
        fmu.display(),
        platforms::size(&fmu)?
    ));
    Ok(Packed {
        fmu,
        linux64: library,
        report,
    })
}

/// Write the archive beside its place and move it there when complete, so that a failure
/// never leaves a partial FMU.
fn pack(fmu: &Path, files: &[(String, PathBuf)]) -> Result {
    let partial = fmu.with_extension("fmu.partial");
    let _ = fs::remove_file(fmu);
    if let Err(error) = write_zip(&partial, files) {
        let _ = fs::remove_file(&partial);
        return Err(error);
    }
    fs::rename(&partial, fmu).map_err(|e| format!("{}: {e}", fmu.display()))
}

fn write_zip(fmu: &Path, files: &[(String, PathBuf)]) -> Result {
    let file = fs::File::create(fmu).map_err(|e| format!("{}: {e}", fmu.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, source) in files {
        let bytes = fs::read(source).map_err(|e| format!("{}: {e}", source.display()))?;
        zip.start_file(name.as_str(), options)
            .map_err(|e| e.to_string())?;
        zip.write_all(&bytes).map_err(|e| e.to_string())?;
    }
    zip.finish().map_err(|e| e.to_string())?;
    Ok(())
}

/// The fmusweep wheel: the native runner, built against glibc 2.17 like the FMU, packed
/// with the Python package by `python/build_wheel.py` (standard library only) as a
/// manylinux_2_17 wheel: workers on older Linux install it too.
fn build_wheel() -> Result<PathBuf> {
    ensure_libclang()?;
    let python = ensure_venv(Packages::Tests)?;
    let runner = build_portable(
        &["--package", "fmu-runner", "--bin", "fmu-runner"],
        "fmu-runner",
    )?;
    check_glibc(&runner)?;
    let wheel = output_of(
        Command::new(&python)
            .arg(root().join("python/build_wheel.py"))
            .arg(&runner)
            .arg(root().join("target/wheels"))
            .arg(format!(
                "manylinux_{}_{}_x86_64",
                GLIBC_BASELINE.0, GLIBC_BASELINE.1
            )),
    )?;
    Ok(PathBuf::from(wheel.trim()))
}

/// Build the wheel and install it in the venv, unless that very wheel is installed.
fn ensure_sweep_package() -> Result<PathBuf> {
    let wheel = build_wheel()?;
    let python = ensure_venv(Packages::Tests)?;
    let stamp = root().join("target/venv/fmusweep.installed.whl");
    let bytes = fs::read(&wheel).map_err(|e| format!("{}: {e}", wheel.display()))?;
    if fs::read(&stamp).is_ok_and(|installed| installed == bytes) {
        return Ok(python);
    }
    println!("xtask: installing {} in the venv", wheel.display());
    run(pip_install(&python)
        .args(["--no-deps", "--force-reinstall"])
        .arg(&wheel))?;
    fs::write(&stamp, bytes).map_err(|e| e.to_string())?;
    Ok(python)
}

/// `cargo xtask sweep SPEC [options]`: the packed FMU is the default FMU of the spec.
fn sweep(args: &[String]) -> Result {
    if args.is_empty() {
        return Err(USAGE.to_string());
    }
    let fmu = build_fmu(false)?.fmu;
    let python = ensure_sweep_package()?;
    // Run where the user is: spec paths are theirs.
    run(Command::new(python)
        .args(["-m", "fmusweep"])
        .args(args)
        .env("FMUSWEEP_FMU", &fmu))
}

fn bench_sweep(args: &[String]) -> Result {
    let fmu = build_fmu(false)?.fmu;
    let python = ensure_sweep_package()?;
    let out = root().join("target/bench-sweep");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    run(Command::new(python)
        .arg(root().join("bench/bench_sweep.py"))
        .arg(&fmu)
        .arg(&out)
        .args(args))
}

fn demo() -> Result {
    let fmu = build_fmu(false)?.fmu;
    let python = ensure_venv(Packages::Demo)?;
    let out = root().join("target/demo");
    run(Command::new(python)
        .arg(root().join("examples/demo.py"))
        .arg(&fmu)
        .arg(&out))
}

/// The benchmark harness, built in a target directory of its own: its peer crates unify
/// features of the build dependencies (fmi-sys's bindgen) differently, and in the shared
/// `target/release` that would rebuild the FMU's library and every test binary on the next
/// `cargo test`, changed or not.
fn build_bench_harness() -> Result<PathBuf> {
    let target = root().join("target/bench-build");
    run(cargo()
        .args(["build", "--release", "--quiet", "--package", "bench"])
        .env("CARGO_TARGET_DIR", &target))?;
    Ok(target.join("release/bench"))
}

fn test() -> Result {
    ensure_libclang()?;
    let reports = root().join("target/test-reports");
    fs::create_dir_all(&reports).map_err(|e| e.to_string())?;
    run(cargo()
        .args(["test", "--release"])
        .env("FUZZ_REPORT", reports.join("fuzz_api.json")))?;
    fuzz_under_valgrind()?;
    // The archive with every platform: the FMPy tests check it as a master would.
    let fmu = test_platforms()?;
    // The benchmark harness builds and drives the packed FMU (a smoke run, no timings
    // judged), so that `cargo xtask bench` keeps working from a fresh clone.
    let harness = build_bench_harness()?;
    let smoke = root().join("target/bench/smoke.json");
    fs::create_dir_all(root().join("target/bench")).map_err(|e| e.to_string())?;
    run(Command::new(&harness)
        .arg(&fmu)
        .arg(&smoke)
        .args(["--quick", "--fmu-only"]))?;
    let python = ensure_sweep_package()?;
    run(Command::new(&python)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(root().join("tests/python"))
        .env("CYCLIC_MECHANISM_FMU", &fmu)
        .current_dir(root()))?;
    // Memcheck of the FMPy suite takes longer than the suite itself; its outcome is decided
    // by the packed FMU, the test files, the installed packages and the selection and
    // options below (in this file) alone.
    let mut inputs = vec![
        fmu.clone(),
        root().join("target/venv/requirements.installed"),
        root().join("xtask/src/main.rs"),
    ];
    inputs.extend(files_with_extension(&root().join("tests/python"), "py")?);
    unless_passed_before("valgrind memcheck of the FMPy suite", &inputs, || {
        fmpy_under_valgrind(&python, &fmu)
    })
}

/// Build the FMU for every platform and run the other platforms' binaries on their ABIs
/// (tests/platforms, xtask/src/abi_tests.rs). Returns the archive.
fn test_platforms() -> Result<PathBuf> {
    ensure_libclang()?;
    let packed = build_fmu(true)?;
    let zig = platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
    abi_tests::test(
        &root().join("target/fmu/assets/modelDescription.xml"),
        &packed.linux64,
        &root().join(PLATFORM_BINARIES),
        &packed.report,
        &zig,
    )?;
    Ok(packed.fmu)
}

/// Run `check` unless it passed before on inputs of exactly these bytes (a fingerprint of
/// their names and contents in `target/passed/`): an unchanged re-run skips it, saying so.
fn unless_passed_before(name: &str, inputs: &[PathBuf], check: impl FnOnce() -> Result) -> Result {
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
fn fingerprint(paths: &[PathBuf]) -> Result<String> {
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

/// The files of `dir` (not its subdirectories) whose names end in `.ext`, sorted.
fn files_with_extension(dir: &Path, ext: &str) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.extension().is_some_and(|e| e == ext))
        .collect();
    files.sort();
    Ok(files)
}

/// The FMPy tests of the C API (argument checks, state machine, FMU state, discards) under
/// valgrind memcheck. Python and numpy have valgrind reports of their own, so
/// only errors with a frame in the FMU's library count, including definite leaks allocated
/// there. A positive control first shows that an overrun inside the library is caught and
/// attributed (tests/python/valgrind_probe.py).
fn fmpy_under_valgrind(python: &Path, fmu: &Path) -> Result {
    let out = root().join("target/valgrind");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    let memcheck = |xml: &Path| {
        let mut command = Command::new("valgrind");
        command
            .args([
                "--leak-check=full",
                "--show-leak-kinds=definite",
                "--error-limit=no",
            ])
            .args(["--xml=yes", &format!("--xml-file={}", xml.display())])
            .arg(python)
            .env("PYTHONMALLOC", "malloc")
            .env("CYCLIC_MECHANISM_FMU", fmu)
            .env("MEASUREMENTS", out.join("measurements.json"))
            .current_dir(root());
        command
    };
    let probe = out.join("probe.xml");
    run(memcheck(&probe)
        .arg(root().join("tests/python/valgrind_probe.py"))
        .arg(fmu))?;
    if errors_in_fmu(&probe)?.is_empty() {
        return Err(
            "valgrind check: the deliberate overrun in valgrind_probe.py was not \
                    attributed to the FMU; the check below would prove nothing"
                .into(),
        );
    }
    let suite = out.join("fmpy_suite.xml");
    let files = [
        "test_fmi_api.py",
        "test_fmu_state.py",
        "test_discard.py",
        // Model Exchange: the state machine, FMU states, Jacobians, and CVODE through the
        // handovers at dead points (the tests against the Python reference are left out:
        // its scipy integration under valgrind takes minutes and exercises no FMU code).
        "test_model_exchange.py::test_bad_states_and_wrong_calls_are_refused_and_change_nothing",
        "test_model_exchange.py::test_fmu_state_restores_model_exchange_exactly",
        "test_model_exchange.py::test_derivatives_match_the_variables_and_states_round_trip",
        "test_model_exchange.py::test_directional_derivatives_are_exact",
        "test_model_exchange.py::test_cvode_hands_over_at_every_dead_point",
    ];
    run(memcheck(&suite)
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .args(files.map(|f| root().join("tests/python").join(f))))?;
    let errors = errors_in_fmu(&suite)?;
    if !errors.is_empty() {
        return Err(format!(
            "valgrind: {} error(s) in the FMU under the FMPy suite (see {}):\n{}",
            errors.len(),
            suite.display(),
            errors.join("\n")
        ));
    }
    println!(
        "xtask: valgrind memcheck of the FMPy suite ({}): no error in the FMU",
        files.join(", ")
    );
    Ok(())
}

/// The kinds and first functions of the errors in valgrind's XML report that have a frame
/// in the FMU's library.
fn errors_in_fmu(xml: &Path) -> Result<Vec<String>> {
    let report = fs::read_to_string(xml).map_err(|e| format!("{}: {e}", xml.display()))?;
    let tag = |block: &str, name: &str| -> Vec<String> {
        let (open, close) = (format!("<{name}>"), format!("</{name}>"));
        block
            .split(&open)
            .skip(1)
            .filter_map(|rest| rest.split(&close).next().map(str::to_string))
            .collect()
    };
    Ok(report
        .split("<error>")
        .skip(1)
        .filter_map(|rest| rest.split("</error>").next())
        .filter(|block| block.contains(&format!("{MODEL_IDENTIFIER}.so")))
        .map(|block| format!("{:?} in {:?}", tag(block, "kind"), tag(block, "fn").first()))
        .collect())
}

/// The fuzzed FMI call sequences again, under valgrind memcheck: no invalid access, no
/// use of uninitialised memory, no definite leak.
fn fuzz_under_valgrind() -> Result {
    if Command::new("valgrind").arg("--version").output().is_err() {
        println!("xtask: installing valgrind");
        apt_install(&["valgrind"])?;
    }
    let runner = "valgrind --error-exitcode=9 --leak-check=full --errors-for-leak-kinds=definite \
                  --show-leak-kinds=definite --quiet";
    run(cargo()
        .args(["test", "--release", "--quiet", "--test", "fuzz_api"])
        .env("CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER", runner)
        .env("CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER", runner)
        .env("FUZZ_SEQUENCES", "300"))
}

/// The compiled peers: bench/compiled/peers.c (the C right-hand side, GSL's rk8pd and
/// CVODE) built against Debian's libgsl-dev and libsundials-dev into
/// target/bench/libpeers.so, and numbalsoda's DOP853 and LSODA libraries (built from
/// PyPI's source with gfortran, without numba). Returns the library and numbalsoda's
/// directory.
fn build_compiled_peers(python: &Path) -> Result<(PathBuf, PathBuf)> {
    let headers = [
        "/usr/include/gsl/gsl_odeiv2.h",
        "/usr/include/cvode/cvode.h",
    ];
    if !headers.iter().all(|h| Path::new(h).exists())
        || Command::new("gfortran").arg("--version").output().is_err()
    {
        println!("xtask: installing gfortran, libgsl-dev and libsundials-dev (the compiled peers)");
        apt_install(&["gfortran", "libgsl-dev", "libsundials-dev"])?;
    }
    let site = python_path(
        python,
        "import sysconfig; print(sysconfig.get_paths()['platlib'])",
    )?
    .join("numbalsoda");
    let pins = root().join("bench/requirements.txt");
    let stamp = site.join("requirements.installed");
    let wanted = fs::read_to_string(&pins).map_err(|e| format!("{}: {e}", pins.display()))?;
    if fs::read_to_string(&stamp).ok().as_deref() != Some(wanted.as_str()) {
        println!("xtask: building numbalsoda's DOP853 and LSODA (bench/requirements.txt)");
        run(Command::new(python)
            .args(["-m", "pip", "install", "--quiet", "--no-deps", "-r"])
            .arg(&pins))?;
        fs::write(&stamp, &wanted).map_err(|e| e.to_string())?;
    }
    let library = root().join("target/bench/libpeers.so");
    run(Command::new("cc")
        .args([
            "-O3", "-shared", "-fPIC", "-Wall", "-Wextra", "-Werror", "-o",
        ])
        .arg(&library)
        .arg(root().join("bench/compiled/peers.c"))
        .args([
            "-lgsl",
            "-lgslcblas",
            "-lsundials_cvode",
            "-lsundials_nvecserial",
        ])
        .args(["-lsundials_sunlinsoldense", "-lsundials_sunmatrixdense"])
        .args(["-lsundials_sunnonlinsolfixedpoint", "-lm"]))?;
    Ok((library, site))
}

/// The work-precision study: the Rust harness (FMU through its C ABI, Rust crates, ns per
/// right-hand side), then the Python driver (reference, scipy, FMPy, table and plot).
fn bench(quick: bool) -> Result {
    let fmu = build_fmu(false)?.fmu;
    let python = ensure_venv(Packages::Tests)?;
    let program = build_bench_harness()?;
    let out = root().join("target/bench");
    fs::create_dir_all(&out).map_err(|e| e.to_string())?;
    let harness = out.join("harness.json");
    let quick_flag: &[&str] = if quick { &["--quick"] } else { &[] };
    // The reference at every communication point first: the harness measures against it.
    run(Command::new(&python)
        .arg(root().join("bench/bench.py"))
        .arg("reference")
        .arg(&out)
        .args(quick_flag))?;
    let (peers, numbalsoda) = build_compiled_peers(&python)?;
    let mut command = Command::new(&program);
    command
        .arg(&fmu)
        .arg(&harness)
        .arg("--reference")
        .arg(&out)
        .arg("--compiled")
        .arg(&peers)
        .arg("--numbalsoda")
        .arg(&numbalsoda)
        .args(quick_flag);
    run(&mut command)?;
    let mut driver = Command::new(python);
    driver
        .arg(root().join("bench/bench.py"))
        .arg(&harness)
        .arg(&fmu)
        .arg(&out);
    if quick {
        driver.arg("--quick");
    }
    run(&mut driver)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The archive holds what was given under its names; a source that cannot be read
    /// leaves no archive, neither a partial one nor the one before.
    #[test]
    fn packing_is_all_or_nothing() {
        let dir = std::env::temp_dir().join(format!("xtask-pack-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let linux = dir.join("linux.so");
        fs::write(&linux, "linux").unwrap();
        let fmu = dir.join("test.fmu");
        let files = vec![("binaries/linux64/CyclicMechanism.so".to_string(), linux)];
        pack(&fmu, &files).unwrap();
        let mut archive = zip::ZipArchive::new(fs::File::open(&fmu).unwrap()).unwrap();
        let names: Vec<String> = archive.file_names().map(str::to_string).collect();
        assert_eq!(names, ["binaries/linux64/CyclicMechanism.so"]);
        let mut content = String::new();
        std::io::Read::read_to_string(&mut archive.by_index(0).unwrap(), &mut content).unwrap();
        assert_eq!(content, "linux");
        let mut broken = files.clone();
        broken.push((
            "binaries/win64/CyclicMechanism.dll".into(),
            dir.join("missing"),
        ));
        let error = pack(&fmu, &broken).unwrap_err();
        assert!(error.contains("missing"), "{error}");
        assert!(!fmu.exists(), "a failed pack leaves no archive");
        assert!(!fmu.with_extension("fmu.partial").exists());
        fs::remove_dir_all(&dir).unwrap();
    }
}
