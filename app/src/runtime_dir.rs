//! A private runtime folder for the Vulkan loader when the session gave none.
//!
//! Mesa's Vulkan device-select layer opens a Wayland connection while it lists the
//! GPUs, and libwayland prints "error: XDG_RUNTIME_DIR is invalid or not set in the
//! environment." (twice) when that variable is unset or not an absolute path, as it is
//! under `ssh`, `sudo`, containers and CI. Nothing is wrong, but a user reads two
//! errors before every command that touches the GPU. Without the variable there is
//! no Wayland session to find, so pointing it at a private folder of our own changes
//! nothing else: palpa sets it before any thread exists.

use std::fs;
use std::io;
use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Whether a value of `XDG_RUNTIME_DIR` is one libwayland accepts (set and absolute).
pub fn is_usable(value: Option<&std::ffi::OsStr>) -> bool {
    value.is_some_and(|v| Path::new(v).is_absolute())
}

/// `base/palpa-runtime-UID`, created with mode 0700 when missing; an existing one is
/// used only if it is a real folder (not a link) owned by `uid` that no one else may
/// enter, so another user cannot plant one for us.
pub fn private_folder(base: &Path, uid: u32) -> io::Result<PathBuf> {
    let dir = base.join(format!("palpa-runtime-{uid}"));
    match fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(e),
    }
    let meta = fs::symlink_metadata(&dir)?;
    if !meta.is_dir() || meta.uid() != uid || meta.permissions().mode() & 0o077 != 0 {
        return Err(io::Error::other(format!(
            "{} is not a private folder of user {uid}",
            dir.display()
        )));
    }
    Ok(dir)
}

/// Sets `XDG_RUNTIME_DIR` to [`private_folder`] under the temporary folder when the
/// session left it unusable. Any failure leaves the environment as it was: the cost
/// is only the loader's complaint.
pub fn ensure() {
    if is_usable(std::env::var_os("XDG_RUNTIME_DIR").as_deref()) {
        return;
    }
    let Ok(uid) = fs::metadata("/proc/self").map(|m| m.uid()) else {
        return;
    };
    let Ok(dir) = private_folder(&std::env::temp_dir(), uid) else {
        return;
    };
    // SAFETY: called first thing in `main`, before any thread is spawned, so no other
    // thread can read the environment while it changes.
    #[allow(unsafe_code)]
    unsafe {
        std::env::set_var("XDG_RUNTIME_DIR", dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_an_absolute_path_is_usable() {
        assert!(!is_usable(None));
        assert!(!is_usable(Some("".as_ref())));
        assert!(!is_usable(Some("relative/dir".as_ref())));
        assert!(is_usable(Some("/run/user/1000".as_ref())));
    }

    #[test]
    fn the_folder_is_made_private_and_a_shared_one_is_refused() {
        let base = std::env::temp_dir().join(format!("palpa-rt-test-{}", std::process::id()));
        fs::create_dir_all(&base).expect("test base");
        let uid = fs::metadata(&base).expect("base").uid();
        let dir = private_folder(&base, uid).expect("made");
        let mode = fs::metadata(&dir).expect("dir").permissions().mode();
        assert_eq!(mode & 0o777, 0o700);
        // Made once, found again.
        assert_eq!(private_folder(&base, uid).expect("found"), dir);
        // Opened to others: refused, not used.
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o755)).expect("chmod");
        assert!(private_folder(&base, uid).is_err());
        // Someone else's: refused.
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o700)).expect("chmod");
        assert!(private_folder(&base, uid.wrapping_add(1)).is_err());
        fs::remove_dir_all(&base).expect("clean up");
    }
}
