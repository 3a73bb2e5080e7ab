//! `cargo xtask fmu [--all-platforms]`: build the library, generate the model description
//! and documentation from the variable table, check every binary and pack the archive.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::cli::Parsed;
use crate::platforms;
use crate::setup::*;
use crate::setup::{Result, MODEL_IDENTIFIER};

/// Where the cross-built binaries are put, checked, under their platform folders.
pub(crate) const PLATFORM_BINARIES: &str = "target/fmu/platforms";

/// `cargo xtask fmu [--all-platforms]`.
pub(crate) fn job(parsed: &Parsed) -> Result {
    let packed = build_fmu(parsed.has("all-platforms"))?;
    for line in &packed.report {
        println!("xtask: {line}");
    }
    println!("FMU: {}", packed.fmu.display());
    println!("FMU (FMI 3.0): {}", packed.fmu3.display());
    Ok(())
}

/// The packed FMUs: the FMI 2.0 and FMI 3.0 archives, the linux64 library in both, and
/// the cross builds' checks.
pub(crate) struct Packed {
    pub(crate) fmu: PathBuf,
    pub(crate) fmu3: PathBuf,
    pub(crate) linux64: PathBuf,
    pub(crate) report: Vec<String>,
}

/// Build the library (against the glibc baseline), generate the model descriptions and
/// documentation from the variable table, and pack `target/fmu/CyclicMechanism.fmu` (FMI
/// 2.0) and `target/fmu/CyclicMechanism-fmi3.fmu` (FMI 3.0) from the same library; with
/// `all_platforms`, the Windows, macOS and aarch64 Linux binaries too (FMI 2.0 has no
/// folder for the latter). Every binary is checked first: a failed check writes no archive.
pub(crate) fn build_fmu(all_platforms: bool) -> Result<Packed> {
    ensure_libclang()?;
    let root = root();
    let library = build_portable_library()?;
    let assets = root.join("target/fmu/assets");
    // Without `--package`: features are then unified over the default members, as for
    // `cargo test`. With it they differ, and the library's cdylib (whose file name carries
    // no hash) would be rebuilt by each in turn, changed or not.
    run(cargo()
        .args(["run", "--release", "--bin", "fmu-assets", "--"])
        .arg(&assets))?;
    let fmu = root.join(format!("target/fmu/{MODEL_IDENTIFIER}.fmu"));
    let fmu3 = root.join(format!("target/fmu/{MODEL_IDENTIFIER}-fmi3.fmu"));
    let mut files3 = vec![
        (
            "modelDescription.xml".to_string(),
            assets.join("fmi3/modelDescription.xml"),
        ),
        (
            format!("binaries/x86_64-linux/{MODEL_IDENTIFIER}.so"),
            library.clone(),
        ),
        (
            "documentation/index.html".to_string(),
            assets.join("index.html"),
        ),
    ];
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
    // The default experiment's result, as the layered standard fmi-ls-ref places it.
    for name in ["fmi-ls-manifest.xml", "CyclicMechanism_out.csv"] {
        for list in [&mut files, &mut files3] {
            list.push((
                format!("extra/org.fmi-standard.fmi-ls-ref/{name}"),
                assets.join("reference").join(name),
            ));
        }
    }
    let mut report = vec![format!(
        "linux64 {}: {} bytes",
        library.display(),
        platforms::size(&library)?
    )];
    if all_platforms {
        let zig = platforms::Zig::find(&ensure_venv(Packages::Demo)?)?;
        let (binaries, checks) = platforms::build_all(&zig, &root.join(PLATFORM_BINARIES))?;
        files.extend(binaries.fmi2_files());
        files3.extend(binaries.fmi3_files());
        report.extend(checks);
    }
    pack(&fmu, &files)?;
    pack(&fmu3, &files3)?;
    for archive in [&fmu, &fmu3] {
        report.push(format!(
            "{}: {} bytes",
            archive.display(),
            platforms::size(archive)?
        ));
    }
    Ok(Packed {
        fmu,
        fmu3,
        linux64: library,
        report,
    })
}

/// The library for `binaries/linux64`, built against glibc 2.17 so that it loads on older
/// Linux (RHEL 7–9, Ubuntu 18.04+), where many industrial FMI tools run.
pub(crate) fn build_portable_library() -> Result<PathBuf> {
    let library = build_portable(
        &["--package", "cyclic-mechanism", "--lib"],
        "libcyclic_mechanism.so",
    )?;
    check_glibc(&library)?;
    Ok(library)
}

/// Write the archive beside its place and move it there when complete (a rename replaces
/// the old archive at once), so that a failure never leaves a partial FMU and another job
/// reading the archive meanwhile reads the old one or the new one, never none. The partial
/// file is this process's own.
pub(crate) fn pack(fmu: &Path, files: &[(String, PathBuf)]) -> Result {
    let partial = fmu.with_extension(format!("fmu.{}.partial", std::process::id()));
    if let Err(error) = write_zip(&partial, files) {
        let _ = fs::remove_file(&partial);
        return Err(error);
    }
    fs::rename(&partial, fmu).map_err(|e| format!("{}: {e}", fmu.display()))
}

pub(crate) fn write_zip(fmu: &Path, files: &[(String, PathBuf)]) -> Result {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The archive holds what was given under its names; a source that cannot be read
    /// leaves no partial archive, and the one before as it was (a reader never finds none).
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
        let before = fs::read(&fmu).unwrap();
        let error = pack(&fmu, &broken).unwrap_err();
        assert!(error.contains("missing"), "{error}");
        assert_eq!(
            fs::read(&fmu).unwrap(),
            before,
            "a failed pack changed the archive"
        );
        let left: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().contains("partial"))
            .collect();
        assert!(left.is_empty(), "a partial archive was left: {left:?}");
        fs::remove_dir_all(&dir).unwrap();
    }
}
