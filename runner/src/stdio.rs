//! The protocol's own channel. An FMU may print to standard output (many do); that must
//! not corrupt the replies, so the runner keeps a private duplicate of the original
//! standard output for the protocol and points file descriptor 1 at standard error.

use std::fs::File;
use std::os::fd::FromRawFd;

pub fn take_protocol_output() -> Result<File, String> {
    // SAFETY: dup and dup2 on the process's own standard descriptors; the new descriptor
    // is owned by the returned File alone.
    unsafe {
        let private = libc::dup(1);
        if private < 0 || libc::dup2(2, 1) < 0 {
            return Err(format!(
                "cannot set up the protocol channel: {}",
                std::io::Error::last_os_error()
            ));
        }
        Ok(File::from_raw_fd(private))
    }
}
