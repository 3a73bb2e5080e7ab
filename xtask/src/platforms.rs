//! The FMU's library for the platforms beside linux64, cross-built on this Debian machine:
//! win64 with MinGW, darwin64 (x86_64 and arm64, joined into one universal Mach-O) and
//! aarch64 Linux with zig as the linker. Debian's `rustc-web` builds the standard library
//! for each target from its sources (`-Zbuild-std`); rustup's toolchain stays the one for
//! the native build. Every binary is checked before it may be packed: exports, imports or
//! linked libraries, architectures and minimum OS.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::setup::{apt_install, clang_include_dir, output_of, python_path, root, run};
use crate::setup::{Result, MODEL_IDENTIFIER};

/// The Debian Rust toolchain that builds the standard library for any target from source,
/// pinned: what every cross build needs, the wasm32 one included.
pub const RUST_PACKAGES: &[(&str, &str)] = &[
    ("rustc-web", "1.96.0+dfsg1-1~deb12u2"),
    ("cargo-web", "1.96.0+dfsg1-1~deb12u2"),
    ("rust-web-src", "1.96.0+dfsg1-1~deb12u2"),
    ("libstd-rust-web-dev", "1.96.0+dfsg1-1~deb12u2"),
];

/// The other Debian packages of the FMU's cross builds, pinned: MinGW's linker and
/// binutils, LLVM's Mach-O tools.
pub const BUILD_PACKAGES: &[(&str, &str)] = &[
    ("gcc-mingw-w64-x86-64", "12.2.0-14+25.2"),
    ("llvm-14", "1:14.0.6-12"),
];

/// The Debian packages that run the other platforms' binaries in the tests: Wine for
/// win64, QEMU and the aarch64 C library for aarch64 Linux.
pub const RUN_PACKAGES: &[(&str, &str)] = &[
    ("wine64", "8.0~repack-4"),
    ("qemu-user-static", "1:7.2+dfsg-7+deb12u18+b3"),
    ("libc6-arm64-cross", "2.36-8cross1"),
];

/// Debian's Rust, which builds the standard library for any target (`rust-web-src`).
pub const DEBIAN_CARGO: &str = "/usr/bin/cargo";
pub const DEBIAN_RUSTC: &str = "/usr/bin/rustc";
pub const LLVM_BIN: &str = "/usr/lib/llvm-14/bin";
pub const MINGW_GCC: &str = "x86_64-w64-mingw32-gcc";

/// The 75 functions of the FMI 3.0 C API (all of `fmi3Functions.h`: FMPy resolves every one
/// when it loads a binary), exported beside FMI 2.0's.
pub const FMI3_FUNCTIONS: [&str; 75] = [
    "fmi3GetVersion",
    "fmi3SetDebugLogging",
    "fmi3InstantiateModelExchange",
    "fmi3InstantiateCoSimulation",
    "fmi3InstantiateScheduledExecution",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3EnterEventMode",
    "fmi3Terminate",
    "fmi3Reset",
    "fmi3GetFloat32",
    "fmi3GetFloat64",
    "fmi3GetInt8",
    "fmi3GetUInt8",
    "fmi3GetInt16",
    "fmi3GetUInt16",
    "fmi3GetInt32",
    "fmi3GetUInt32",
    "fmi3GetInt64",
    "fmi3GetUInt64",
    "fmi3GetBoolean",
    "fmi3GetString",
    "fmi3GetBinary",
    "fmi3GetClock",
    "fmi3SetFloat32",
    "fmi3SetFloat64",
    "fmi3SetInt8",
    "fmi3SetUInt8",
    "fmi3SetInt16",
    "fmi3SetUInt16",
    "fmi3SetInt32",
    "fmi3SetUInt32",
    "fmi3SetInt64",
    "fmi3SetUInt64",
    "fmi3SetBoolean",
    "fmi3SetString",
    "fmi3SetBinary",
    "fmi3SetClock",
    "fmi3GetNumberOfVariableDependencies",
    "fmi3GetVariableDependencies",
    "fmi3GetFMUState",
    "fmi3SetFMUState",
    "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState",
    "fmi3GetDirectionalDerivative",
    "fmi3GetAdjointDerivative",
    "fmi3EnterConfigurationMode",
    "fmi3ExitConfigurationMode",
    "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction",
    "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction",
    "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction",
    "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction",
    "fmi3EvaluateDiscreteStates",
    "fmi3UpdateDiscreteStates",
    "fmi3EnterContinuousTimeMode",
    "fmi3CompletedIntegratorStep",
    "fmi3SetTime",
    "fmi3SetContinuousStates",
    "fmi3GetContinuousStateDerivatives",
    "fmi3GetEventIndicators",
    "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfContinuousStates",
    "fmi3EnterStepMode",
    "fmi3GetOutputDerivatives",
    "fmi3DoStep",
    "fmi3ActivateModelPartition",
];

/// Every function a binary exports, and all that it exports.
fn fmi_functions() -> impl Iterator<Item = &'static str> {
    FMI2_FUNCTIONS.iter().chain(FMI3_FUNCTIONS.iter()).copied()
}

/// The minimum macOS of each darwin slice: what a Dymola or Simulink user on an older Mac
/// still has (High Sierra on Intel; Big Sur, the first for Apple silicon).
const MACOS_X86_64: &str = "10.13";
const MACOS_ARM64: &str = "11.0";

/// The 44 functions of the FMI 2.0 C API (Co-Simulation and Model Exchange).
pub const FMI2_FUNCTIONS: [&str; 44] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
];

/// Exports that the PE and Mach-O linkers add beside the FMI functions, each for a reason
/// no flag of theirs removes: fmi-sys's `#[no_mangle]` logging helper, which rustc lists
/// in the DLL's `.def` file and marks visible on macOS (ELF's version script hides it);
/// and, on macOS, the image's own header and DSO handle and compiler-rt's two OS-version
/// helpers, which zig's Mach-O linker exports because it takes no export list.
const ALLOWED_EXTRA_PE: &[&str] = &["callback_log"];
const ALLOWED_EXTRA_MACHO: &[&str] = &[
    "callback_log",
    "_mh_dylib_header",
    "__dso_handle",
    "__isOSVersionAtLeast",
    "__isPlatformVersionAtLeast",
];

/// The DLLs the win64 binary may import: Windows' own (Windows 10 or later, Rust's floor
/// for this target), so that nothing needs to be shipped beside it.
const WINDOWS_SYSTEM_DLLS: &[&str] = &[
    "kernel32.dll",
    "msvcrt.dll",
    "ntdll.dll",
    "userenv.dll",
    "ws2_32.dll",
    "api-ms-win-core-synch-l1-2-0.dll",
    "bcryptprimitives.dll",
];

/// The shared libraries the aarch64 Linux binary may need: glibc's.
const GLIBC_LIBRARIES: &[&str] = &[
    "libc.so.6",
    "libm.so.6",
    "libdl.so.2",
    "libpthread.so.0",
    "ld-linux-aarch64.so.1",
];

/// A platform the crate is cross-built for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    Win64,
    DarwinX86_64,
    DarwinArm64,
    LinuxAarch64,
}

impl Target {
    pub const ALL: [Target; 4] = [
        Target::Win64,
        Target::DarwinX86_64,
        Target::DarwinArm64,
        Target::LinuxAarch64,
    ];

    /// Rust's target triple.
    pub fn triple(self) -> &'static str {
        match self {
            Target::Win64 => "x86_64-pc-windows-gnu",
            Target::DarwinX86_64 => "x86_64-apple-darwin",
            Target::DarwinArm64 => "aarch64-apple-darwin",
            Target::LinuxAarch64 => "aarch64-unknown-linux-gnu",
        }
    }

    /// The library's file name in the target's release folder.
    fn artifact(self) -> &'static str {
        match self {
            Target::Win64 => "cyclic_mechanism.dll",
            Target::DarwinX86_64 | Target::DarwinArm64 => "libcyclic_mechanism.dylib",
            Target::LinuxAarch64 => "libcyclic_mechanism.so",
        }
    }

    fn uses_zig(self) -> bool {
        self != Target::Win64
    }
}

/// Where the cross builds keep their target folders: outside the checkout (by default in
/// the user's cache), so that a fresh clone on the same machine does not build the
/// standard library again for every target. `CROSS_TARGET_DIR` overrides it.
pub fn cross_target_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("CROSS_TARGET_DIR") {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|home| PathBuf::from(home).join(".cache")))
        .unwrap_or_else(|| root().join("target"));
    cache.join("cyclic-mechanism-cross")
}

/// Install each pinned package that is missing. A package already installed at another
/// version is used as it is, with a note.
pub fn ensure_packages(packages: &[(&str, &str)]) -> Result {
    let mut missing = Vec::new();
    for (name, pinned) in packages {
        let installed = Command::new("dpkg-query")
            .args(["-W", "-f=${Version} ${Status}", name])
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
            .filter(|text| text.ends_with("install ok installed"));
        match installed {
            None => missing.push(format!("{name}={pinned}")),
            Some(text) if !text.starts_with(&format!("{pinned} ")) => println!(
                "xtask: note: {name} {} is installed; the pin is {pinned}",
                text.split(' ').next().unwrap_or_default()
            ),
            Some(_) => {}
        }
    }
    if missing.is_empty() {
        return Ok(());
    }
    println!("xtask: installing {}", missing.join(" "));
    let refs: Vec<&str> = missing.iter().map(String::as_str).collect();
    apt_install(&refs).map_err(|e| {
        format!(
            "{e}\nthe pinned Debian packages ({}) could not be installed; if Debian has \
             replaced them by a newer point release, update the pins in xtask/src/platforms.rs",
            refs.join(" ")
        )
    })
}

/// What the cross builds need from the native set-up: the venv's bin folder, a folder
/// with the pinned zig as `zig` (cargo-zigbuild then also hands bindgen zig's headers for
/// darwin), and zig's own C headers.
pub struct Zig {
    pub venv_bin: PathBuf,
    zig_bin: PathBuf,
    pub lib: PathBuf,
}

impl Zig {
    pub fn find(python: &Path) -> Result<Zig> {
        let package = python_path(
            python,
            "import os, ziglang; print(os.path.dirname(ziglang.__file__))",
        )
        .map_err(|e| {
            format!("{e}\nthe venv needs the ziglang of tests/python/requirements-demo.txt")
        })?;
        let zig_bin = root().join("target/platforms/zig-bin");
        let link = zig_bin.join("zig");
        if fs::read_link(&link).ok().as_deref() != Some(package.join("zig").as_path()) {
            fs::create_dir_all(&zig_bin).map_err(|e| e.to_string())?;
            let _ = fs::remove_file(&link);
            std::os::unix::fs::symlink(package.join("zig"), &link)
                .map_err(|e| format!("{}: {e}", link.display()))?;
        }
        Ok(Zig {
            venv_bin: python
                .parent()
                .ok_or("the venv's bin folder")?
                .to_path_buf(),
            zig_bin,
            lib: package.join("lib"),
        })
    }

    /// `zig cc` for `target` (a zig triple, with a glibc version where it matters).
    pub fn cc(&self, target: &str) -> Command {
        let mut command = Command::new(self.venv_bin.join("python"));
        command.args(["-m", "ziglang", "cc", "-target", target]);
        command
    }

    /// `PATH` with zig's folder and the venv's bin folder first.
    pub fn path(&self) -> Result<std::ffi::OsString> {
        std::env::join_paths(
            [self.zig_bin.clone(), self.venv_bin.clone()]
                .into_iter()
                .chain(std::env::split_paths(
                    &std::env::var_os("PATH").unwrap_or_default(),
                )),
        )
        .map_err(|e| e.to_string())
    }
}

/// Debian's cargo with the environment that builds the standard library for `target`:
/// `subcommand` is `build` or `test` (MinGW) or `zigbuild` (zig links).
pub fn cross_cargo(target: Target, subcommand: &str, zig: &Zig) -> Result<Command> {
    let mut command = Command::new(DEBIAN_CARGO);
    let subcommand = if target.uses_zig() && subcommand == "build" {
        "zigbuild"
    } else {
        subcommand
    };
    let triple = match target {
        // The glibc baseline of linux64 for aarch64 too.
        Target::LinuxAarch64 => format!("{}.2.17", target.triple()),
        _ => target.triple().to_string(),
    };
    // zig gives the paths of its headers relative to the working directory when they lie
    // below it (the venv is in the checkout); bindgen, run in another folder, needs them
    // absolute: cargo runs outside the checkout.
    let cwd = cross_target_dir();
    fs::create_dir_all(&cwd).map_err(|e| format!("{}: {e}", cwd.display()))?;
    command
        .current_dir(&cwd)
        .arg(subcommand)
        .arg("--manifest-path")
        .arg(root().join("Cargo.toml"))
        .args(["--release", "--quiet", "--target", &triple])
        .arg("-Zbuild-std=std,panic_unwind")
        .env("RUSTC", DEBIAN_RUSTC)
        .env("RUSTDOC", "/usr/bin/rustdoc")
        .env("RUSTC_BOOTSTRAP", "1")
        // The tests' build of the library unifies features with the dev-dependencies: in
        // a folder of its own, so that the two builds do not relink each other by turns.
        .env(
            "CARGO_TARGET_DIR",
            cross_target_dir().join(if subcommand == "test" {
                format!("{}-tests", target.triple())
            } else {
                target.triple().to_string()
            }),
        )
        .env("PATH", zig.path()?)
        // Set by the cargo that runs xtask; they would point Debian's cargo at rustup's.
        .env_remove("CARGO")
        .env_remove("RUSTUP_TOOLCHAIN")
        .env_remove("CARGO_MANIFEST_DIR");
    target_environment(&mut command, target, zig)?;
    Ok(command)
}

/// What each cross target's build needs of its own: the linker, stripping, visibility,
/// the macOS deployment target, and the headers bindgen is to see.
fn target_environment(command: &mut Command, target: Target, zig: &Zig) -> Result {
    let clang = clang_include_dir()?;
    let bindgen = format!(
        "BINDGEN_EXTRA_CLANG_ARGS_{}",
        target.triple().replace('-', "_")
    );
    let rustflags = format!(
        "CARGO_TARGET_{}_RUSTFLAGS",
        target.triple().replace('-', "_").to_uppercase()
    );
    match target {
        Target::Win64 => {
            command
                .env("CARGO_TARGET_X86_64_PC_WINDOWS_GNU_LINKER", MINGW_GCC)
                // The linker drops the symbol table (a DLL exports by its export table);
                // MinGW's strip would also write the time of day into the header, and the
                // same sources would no longer give the same bytes.
                .env("CARGO_PROFILE_RELEASE_STRIP", "symbols")
                // MinGW's malloc.h includes mm_malloc.h, one of clang's own headers.
                .env(bindgen, format!("-isystem {}", clang.display()));
        }
        Target::DarwinX86_64 | Target::DarwinArm64 => {
            let minimum = if target == Target::DarwinX86_64 {
                MACOS_X86_64
            } else {
                MACOS_ARM64
            };
            command
                .env("MACOSX_DEPLOYMENT_TARGET", minimum)
                // rustc strips Apple binaries with rust-objcopy, which Debian's Rust lacks
                // (and which would invalidate the arm64 slice's signature); zig's `-s`
                // drops the debug symbols at link time instead, before it signs.
                .env("CARGO_PROFILE_RELEASE_STRIP", "false")
                // zig's Mach-O linker takes no export list: hidden visibility keeps the
                // standard library's symbols out of the export table.
                .env(rustflags, "-Zdefault-visibility=hidden -Clink-arg=-s");
        }
        Target::LinuxAarch64 => {
            // cargo-zigbuild cannot collect include paths for a versioned glibc triple:
            // bindgen gets zig's aarch64 glibc headers.
            let libc = zig.lib.join("libc/include");
            command.env(
                bindgen,
                format!(
                    "-isystem {} -isystem {} -isystem {} -isystem {}",
                    clang.display(),
                    libc.join("aarch64-linux-gnu").display(),
                    libc.join("generic-glibc").display(),
                    libc.join("any-linux-any").display()
                ),
            );
        }
    }
    Ok(())
}

/// Files to pack, as (path in the FMU, file).
pub type Files = Vec<(String, PathBuf)>;

/// A binary built and checked, ready to pack.
pub struct Built {
    pub target: Target,
    pub library: PathBuf,
    pub seconds: f64,
}

/// Build the library for `target` (only what changed is rebuilt).
pub fn build(target: Target, zig: &Zig) -> Result<Built> {
    println!("xtask: building the library for {}", target.triple());
    let started = Instant::now();
    run(cross_cargo(target, "build", zig)?.args(["--package", "cyclic-mechanism", "--lib"]))?;
    let library = cross_target_dir()
        .join(target.triple())
        .join(target.triple())
        .join("release")
        .join(target.artifact());
    Ok(Built {
        target,
        library,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Every target's library, [`Target::ALL`]'s order, two builds at a time. A cross build
/// is mostly single-threaded work: with one codegen unit per crate the standard library's
/// crates compile one after another, and the fat-LTO link of the library is one thread;
/// two builds at once keep both of a small machine's cores busy. Each target has a target
/// folder of its own, so the two cargos do not wait for each other's lock.
fn build_in_two_lanes(zig: &Zig) -> Result<Vec<Built>> {
    let lane = |parity: usize| -> Result<Vec<Built>> {
        Target::ALL
            .iter()
            .skip(parity)
            .step_by(2)
            .map(|&target| build(target, zig))
            .collect()
    };
    let (even, odd) = std::thread::scope(|scope| {
        let odd = scope.spawn(|| lane(1));
        let even = lane(0);
        let odd = odd
            .join()
            .unwrap_or_else(|_| Err("a cross build's thread panicked".into()));
        (even, odd)
    });
    let mut built = even?;
    built.extend(odd?);
    built.sort_by_key(|b| Target::ALL.iter().position(|t| *t == b.target));
    Ok(built)
}

/// The cross-built binaries, checked, under `dir`.
pub struct Binaries {
    pub win64: PathBuf,
    /// x86_64 and arm64 joined: FMI 2.0's darwin64 folder holds one file for both.
    pub darwin_universal: PathBuf,
    pub darwin_x86_64: PathBuf,
    pub darwin_arm64: PathBuf,
    pub linux_aarch64: PathBuf,
}

impl Binaries {
    /// The files of the FMI 2.0 archive: its platform folders (aarch64 Linux has none).
    pub fn fmi2_files(&self) -> Files {
        vec![
            (
                format!("binaries/win64/{MODEL_IDENTIFIER}.dll"),
                self.win64.clone(),
            ),
            (
                format!("binaries/darwin64/{MODEL_IDENTIFIER}.dylib"),
                self.darwin_universal.clone(),
            ),
        ]
    }

    /// The files of the FMI 3.0 archive, under its platform tuples.
    pub fn fmi3_files(&self) -> Files {
        vec![
            (
                format!("binaries/x86_64-windows/{MODEL_IDENTIFIER}.dll"),
                self.win64.clone(),
            ),
            (
                format!("binaries/x86_64-darwin/{MODEL_IDENTIFIER}.dylib"),
                self.darwin_x86_64.clone(),
            ),
            (
                format!("binaries/aarch64-darwin/{MODEL_IDENTIFIER}.dylib"),
                self.darwin_arm64.clone(),
            ),
            (
                format!("binaries/aarch64-linux/{MODEL_IDENTIFIER}.so"),
                self.linux_aarch64.clone(),
            ),
        ]
    }
}

/// The binaries for win64, darwin (each architecture, and both joined into a universal
/// Mach-O) and aarch64 Linux, built (stripped by their linkers), checked, and copied to
/// `dir`. Returns them with a line per binary for the report.
pub fn build_all(zig: &Zig, dir: &Path) -> Result<(Binaries, Vec<String>)> {
    ensure_packages(RUST_PACKAGES)?;
    ensure_packages(BUILD_PACKAGES)?;
    let built = build_in_two_lanes(zig)?;
    let by = |target: Target| &built[Target::ALL.iter().position(|t| *t == target).unwrap()];
    let _ = fs::remove_dir_all(dir);
    let binaries = Binaries {
        win64: dir.join(format!("win64/{MODEL_IDENTIFIER}.dll")),
        darwin_universal: dir.join(format!("darwin64/{MODEL_IDENTIFIER}.dylib")),
        darwin_x86_64: dir.join(format!("x86_64-darwin/{MODEL_IDENTIFIER}.dylib")),
        darwin_arm64: dir.join(format!("aarch64-darwin/{MODEL_IDENTIFIER}.dylib")),
        linux_aarch64: dir.join(format!("aarch64-linux/{MODEL_IDENTIFIER}.so")),
    };
    let copies = [
        (Target::Win64, &binaries.win64),
        (Target::DarwinX86_64, &binaries.darwin_x86_64),
        (Target::DarwinArm64, &binaries.darwin_arm64),
        (Target::LinuxAarch64, &binaries.linux_aarch64),
    ];
    for (target, file) in copies {
        fs::create_dir_all(file.parent().unwrap()).map_err(|e| e.to_string())?;
        fs::copy(&by(target).library, file).map_err(|e| e.to_string())?;
    }
    fs::create_dir_all(binaries.darwin_universal.parent().unwrap()).map_err(|e| e.to_string())?;
    run(Command::new(Path::new(LLVM_BIN).join("llvm-lipo"))
        .arg("-create")
        .arg(&binaries.darwin_x86_64)
        .arg(&binaries.darwin_arm64)
        .arg("-output")
        .arg(&binaries.darwin_universal))?;
    let mut report = vec![
        check_pe(&binaries.win64)?,
        check_macho(&binaries.darwin_universal)?,
        check_aarch64_elf(&binaries.linux_aarch64)?,
    ];
    for b in &built {
        report.push(format!(
            "{}: built in {:.0} s, {} bytes",
            b.target.triple(),
            b.seconds,
            size(&b.library)?
        ));
    }
    Ok((binaries, report))
}

pub fn size(path: &Path) -> Result<u64> {
    fs::metadata(path)
        .map(|m| m.len())
        .map_err(|e| format!("{}: {e}", path.display()))
}

fn llvm(tool: &str) -> Command {
    Command::new(Path::new(LLVM_BIN).join(tool))
}

/// The exports must be the FMI 2.0 and 3.0 functions, plus at most the linker's
/// extras.
fn check_exports(binary: &Path, exported: &[String], allowed: &[&str]) -> Result<String> {
    let expected: Vec<&str> = fmi_functions().collect();
    let missing: Vec<&str> = expected
        .iter()
        .copied()
        .filter(|f| !exported.iter().any(|e| e == f))
        .collect();
    let unexpected: Vec<&String> = exported
        .iter()
        .filter(|e| !expected.contains(&e.as_str()) && !allowed.contains(&e.as_str()))
        .collect();
    if !missing.is_empty() || !unexpected.is_empty() {
        return Err(format!(
            "{}: exports must be the {} FMI 2.0 and 3.0 functions; missing {missing:?},              unexpected {} such as {:?}",
            binary.display(),
            expected.len(),
            unexpected.len(),
            unexpected.iter().take(5).collect::<Vec<_>>()
        ));
    }
    let extras: Vec<&String> = exported
        .iter()
        .filter(|e| !expected.contains(&e.as_str()))
        .collect();
    Ok(format!(
        "{} FMI functions exported{}",
        expected.len(),
        if extras.is_empty() {
            String::new()
        } else {
            format!(" (and the linker's {extras:?})")
        }
    ))
}

/// The win64 DLL: its exports and imported DLLs.
fn check_pe(dll: &Path) -> Result<String> {
    let dump = output_of(
        Command::new("x86_64-w64-mingw32-objdump")
            .arg("-p")
            .arg(dll),
    )?;
    let exported: Vec<String> = dump
        .split("[Ordinal/Name Pointer] Table")
        .nth(1)
        .ok_or_else(|| format!("{}: no export table", dll.display()))?
        .lines()
        .skip(1)
        .take_while(|line| line.trim_start().starts_with('['))
        .filter_map(|line| line.split(']').nth(1).map(|n| n.trim().to_string()))
        .collect();
    let exports = check_exports(dll, &exported, ALLOWED_EXTRA_PE)?;
    let mut imports: Vec<String> = dump
        .lines()
        .filter_map(|line| line.trim().strip_prefix("DLL Name: "))
        .map(str::to_ascii_lowercase)
        .collect();
    imports.sort();
    imports.dedup();
    let foreign: Vec<&String> = imports
        .iter()
        .filter(|dll| !WINDOWS_SYSTEM_DLLS.contains(&dll.as_str()))
        .collect();
    if !foreign.is_empty() {
        return Err(format!(
            "{}: imports {foreign:?}, which Windows does not have: only system DLLs may be \
             imported ({WINDOWS_SYSTEM_DLLS:?})",
            dll.display()
        ));
    }
    Ok(format!(
        "win64 {}: {} bytes, PE32+ x86-64; {exports}; imports only {}",
        dll.display(),
        size(dll)?,
        imports.join(", ")
    ))
}

/// The universal Mach-O: both architectures, each with its minimum macOS, libSystem alone,
/// the FMI exports, and a code signature on the arm64 slice (Apple silicon runs no
/// unsigned code; zig signs it ad hoc).
fn check_macho(dylib: &Path) -> Result<String> {
    let archs = output_of(llvm("llvm-lipo").arg("-archs").arg(dylib))?;
    let archs: Vec<&str> = archs.split_whitespace().collect();
    if archs != ["x86_64", "arm64"] {
        return Err(format!(
            "{}: architectures {archs:?}, not x86_64 and arm64",
            dylib.display()
        ));
    }
    let mut lines = Vec::new();
    for (arch, minimum) in [("x86_64", MACOS_X86_64), ("arm64", MACOS_ARM64)] {
        let headers = output_of(
            llvm("llvm-objdump")
                .args(["--macho", "--private-headers", "--arch", arch])
                .arg(dylib),
        )?;
        let minos = minimum_macos(&headers);
        if minos != minimum {
            return Err(format!(
                "{} ({arch}): minimum macOS {minos}, not {minimum}",
                dylib.display()
            ));
        }
        if arch == "arm64" && !headers.contains("LC_CODE_SIGNATURE") {
            return Err(format!("{} (arm64): no code signature", dylib.display()));
        }
        let used = output_of(
            llvm("llvm-objdump")
                .args(["--macho", "--dylibs-used", "--arch", arch])
                .arg(dylib),
        )?;
        // The first is the library's own name; every other must be libSystem.
        let libraries: Vec<&str> = used
            .lines()
            .skip(2)
            .filter_map(|l| l.split_whitespace().next())
            .collect();
        if libraries != ["/usr/lib/libSystem.B.dylib"] {
            return Err(format!(
                "{} ({arch}): links {libraries:?}; only /usr/lib/libSystem.B.dylib may be linked",
                dylib.display()
            ));
        }
        let trie = output_of(
            llvm("llvm-objdump")
                .args(["--macho", "--exports-trie", "--arch", arch])
                .arg(dylib),
        )?;
        let exported: Vec<String> = trie
            .lines()
            .filter(|l| l.starts_with("0x"))
            .filter_map(|l| l.split_whitespace().nth(1))
            // Mach-O prefixes C names with an underscore.
            .map(|name| name.strip_prefix('_').unwrap_or(name).to_string())
            .collect();
        let exports = check_exports(dylib, &exported, ALLOWED_EXTRA_MACHO)?;
        lines.push(format!(
            "{arch}: minimum macOS {minos}, links libSystem only; {exports}"
        ));
    }
    Ok(format!(
        "darwin64 {}: {} bytes, universal Mach-O; {}",
        dylib.display(),
        size(dylib)?,
        lines.join("; ")
    ))
}

/// The minimum macOS of `llvm-objdump --private-headers`: `minos` of LC_BUILD_VERSION, or
/// `version` of the older LC_VERSION_MIN_MACOSX, which zig writes for targets before 10.14.
fn minimum_macos(headers: &str) -> String {
    let mut lines = headers.lines().map(str::trim);
    while let Some(line) = lines.next() {
        let key = match line {
            "cmd LC_BUILD_VERSION" => "minos ",
            "cmd LC_VERSION_MIN_MACOSX" => "version ",
            _ => continue,
        };
        if let Some(value) = lines.by_ref().take(4).find_map(|l| l.strip_prefix(key)) {
            return value.trim().to_string();
        }
    }
    "none".to_string()
}

/// The aarch64 Linux library: glibc 2.17 at most, glibc's libraries alone, the FMI exports.
fn check_aarch64_elf(library: &Path) -> Result<String> {
    crate::setup::check_glibc(library)?;
    let dynamic = output_of(llvm("llvm-readelf").args(["--dynamic", "-h"]).arg(library))?;
    if !dynamic.contains("AArch64") {
        return Err(format!("{}: not an AArch64 ELF", library.display()));
    }
    let needed: Vec<String> = dynamic
        .lines()
        .filter(|l| l.contains("(NEEDED)"))
        .filter_map(|l| {
            l.split('[')
                .nth(1)
                .map(|n| n.trim_end_matches(']').to_string())
        })
        .collect();
    if let Some(other) = needed
        .iter()
        .find(|n| !GLIBC_LIBRARIES.contains(&n.as_str()))
    {
        return Err(format!(
            "{}: needs {other}; only glibc's libraries may be needed",
            library.display()
        ));
    }
    let symbols = output_of(
        llvm("llvm-nm")
            .args(["--dynamic", "--defined-only", "--extern-only"])
            .arg(library),
    )?;
    let exported: Vec<String> = symbols
        .lines()
        .filter_map(|l| l.split_whitespace().nth(2).map(str::to_string))
        .collect();
    let exports = check_exports(library, &exported, &[])?;
    Ok(format!(
        "aarch64 Linux {}: {} bytes; {exports}; needs {}",
        library.display(),
        size(library)?,
        needed.join(", ")
    ))
}
