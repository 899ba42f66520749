//! Where cpmx's tests find SigmaRL's reference data: `../shared/reference` beside the
//! checkout, or the folder `CPMX_REFERENCE_DIR` names. A test that needs it asks here first, so
//! that without it the test fails with one line naming the folder, never with a bare panic
//! on a missing file (and never passes silently).
//!
//! The data is made with SigmaRL's own code (its `README.md` says how each file was made) and
//! is never copied into the repository.

use std::path::{Component, Path, PathBuf};

/// The variable that points the tests at another copy of the reference data.
pub const OVERRIDE: &str = "CPMX_REFERENCE_DIR";

/// The folder where the reference data is expected, whether it is there or not:
/// `CPMX_REFERENCE_DIR`, else `../shared/reference` beside the checkout, as an absolute path.
pub fn reference_dir() -> PathBuf {
    match std::env::var_os(OVERRIDE) {
        Some(dir) if !dir.is_empty() => absolute(Path::new(&dir)),
        _ => normal(&checkout().join("../shared/reference")),
    }
}

/// The checkout (the workspace's root folder).
pub fn checkout() -> PathBuf {
    normal(&Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
}

/// The reference data folder; fails the calling test with the message of [`missing`] when it
/// is not there.
#[track_caller]
pub fn reference() -> PathBuf {
    let dir = reference_dir();
    if !dir.is_dir() {
        panic!("{}", missing(&dir));
    }
    dir
}

/// A file or folder of the reference data (`maps/cpm.xml`); fails the calling test with the
/// message of [`missing`] when the folder or the file is not there.
#[track_caller]
pub fn reference_file(relative: &str) -> PathBuf {
    let path = reference().join(relative);
    if !path.exists() {
        panic!("{}", missing(&path));
    }
    path
}

/// The text of a file of the reference data.
#[track_caller]
pub fn read_reference(relative: &str) -> String {
    let path = reference_file(relative);
    match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(error) => panic!("cannot read SigmaRL's reference data {}: {error}", path.display()),
    }
}

/// Whether the reference data folder is there (for helpers that pass it on when it is).
pub fn reference_available() -> bool {
    reference_dir().is_dir()
}

/// The one line every test that needs the data prints without it.
pub fn missing(path: &Path) -> String {
    let source = if std::env::var_os(OVERRIDE).is_some_and(|d| !d.is_empty()) {
        OVERRIDE.to_owned()
    } else {
        "../shared/reference beside the checkout; CPMX_REFERENCE_DIR overrides it".to_owned()
    };
    format!(
        "needs SigmaRL's reference data at {} ({source}): not found",
        path.display()
    )
}

fn absolute(path: &Path) -> PathBuf {
    if path.is_absolute() {
        normal(path)
    } else {
        let here = std::env::current_dir().unwrap_or_default();
        normal(&here.join(path))
    }
}

/// `a/b/../c` as `a/c`, without touching the file system (the folder may not exist).
fn normal(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for component in path.components() {
        match component {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_folder_is_beside_the_checkout() {
        if std::env::var_os(OVERRIDE).is_some() {
            return;
        }
        let dir = reference_dir();
        assert!(dir.is_absolute());
        assert_eq!(
            dir.parent().unwrap().parent().unwrap(),
            checkout().parent().unwrap()
        );
        assert!(dir.ends_with("shared/reference"));
    }

    #[test]
    fn the_message_names_the_folder() {
        let text = missing(Path::new("/nowhere/shared/reference"));
        assert!(text.starts_with("needs SigmaRL's reference data at /nowhere/shared/reference ("));
        assert!(text.ends_with("): not found"));
    }
}
