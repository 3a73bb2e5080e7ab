//! A `.fmu` archive unpacked into a folder of its own, removed again when dropped.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// An unpacked FMU.
pub struct Unpacked {
    dir: PathBuf,
}

impl Unpacked {
    /// Unpack `fmu` into a new folder under the system's temporary folder.
    pub fn new(fmu: &Path) -> Result<Self, String> {
        Self::within(fmu, &std::env::temp_dir())
    }

    /// Unpack `fmu` into a new folder under `parent` (a folder whose owner removes it
    /// with everything inside, should this process end before dropping the result).
    pub fn within(fmu: &Path, parent: &Path) -> Result<Self, String> {
        static COUNT: AtomicU64 = AtomicU64::new(0);
        let file = std::fs::File::open(fmu).map_err(|e| format!("{}: {e}", fmu.display()))?;
        let mut archive =
            zip::ZipArchive::new(file).map_err(|e| format!("{}: {e}", fmu.display()))?;
        let dir = parent.join(format!(
            "fmu-runner-{}-{}",
            std::process::id(),
            COUNT.fetch_add(1, Ordering::Relaxed)
        ));
        // Owned from here on: a failed extraction removes what it wrote.
        let unpacked = Self { dir };
        archive
            .extract(&unpacked.dir)
            .map_err(|e| format!("{}: {e}", fmu.display()))?;
        Ok(unpacked)
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Unpacked {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
