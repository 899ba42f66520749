//! The data path: where a relative file named in a spec is looked for.
//!
//! In order: the spec's folder, each `--data DIR`, each folder of `CPMX_DATA`
//! (colon-separated). The first folder that has the file wins; when none has it, the error
//! lists every place that was tried. A file pinned by its SHA-256 is the first one found
//! with that content: a run folder's resolved spec pins its map and weights this way, so a
//! folder moved elsewhere finds them again on `--data`, and never a different file of the
//! same name.

use std::path::{Path, PathBuf};

/// The folders a relative file is looked up in, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DataPath {
    pub folders: Vec<PathBuf>,
    /// How the caller adds a folder, as help lines name it: [`COMMAND_LINE`] (`--data DIR`) or
    /// [`PYTHON`] (`data=`).
    pub option: &'static str,
}

/// The command line's way to add a data folder.
pub const COMMAND_LINE: &str = "`--data DIR`";
/// Python's way (`cpmx.VecEnv(spec, data=...)`, `cpmx.run(spec, data=...)`).
pub const PYTHON: &str = "`data=`";

impl Default for DataPath {
    fn default() -> Self {
        Self {
            folders: Vec::new(),
            option: COMMAND_LINE,
        }
    }
}

impl DataPath {
    /// The data path of a spec in `spec_dir`, with `--data` folders and the `CPMX_DATA` value.
    pub fn new(spec_dir: &Path, data_dirs: &[PathBuf], cpmx_data: Option<&str>) -> Self {
        let mut folders = vec![spec_dir.to_path_buf()];
        folders.extend(data_dirs.iter().cloned());
        if let Some(var) = cpmx_data {
            folders.extend(var.split(':').filter(|s| !s.is_empty()).map(PathBuf::from));
        }
        Self {
            folders,
            option: COMMAND_LINE,
        }
    }

    /// The same data path, its help lines naming `option` as the way to add a folder.
    pub fn named(self, option: &'static str) -> Self {
        Self { option, ..self }
    }

    /// The file, or the list of paths that were tried.
    pub fn find(&self, file: &str) -> Result<PathBuf, Vec<PathBuf>> {
        let path = Path::new(file);
        if path.is_absolute() {
            return if path.exists() {
                Ok(path.to_path_buf())
            } else {
                Err(vec![path.to_path_buf()])
            };
        }
        let tried: Vec<PathBuf> = self.folders.iter().map(|f| f.join(path)).collect();
        tried.iter().find(|p| p.exists()).cloned().ok_or(tried)
    }
}

/// Why a file was not found: every place tried, and the files of that name whose content
/// differed from the pinned hash.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotFound {
    pub tried: Vec<PathBuf>,
    /// Files that exist but have another SHA-256 (path, their hash).
    pub other_content: Vec<(PathBuf, String)>,
}

impl DataPath {
    /// The first file named `file` whose SHA-256 is `sha256` (any content when `None`).
    pub fn find_pinned(&self, file: &str, sha256: Option<&str>) -> Result<PathBuf, NotFound> {
        let path = Path::new(file);
        let candidates: Vec<PathBuf> = if path.is_absolute() {
            vec![path.to_path_buf()]
        } else {
            self.folders.iter().map(|f| f.join(path)).collect()
        };
        let mut other_content = Vec::new();
        for candidate in &candidates {
            // A pinned file must be a readable file; an unpinned name may be a folder too.
            let usable = candidate.is_file() || (sha256.is_none() && candidate.exists());
            if !usable {
                continue;
            }
            let Some(expected) = sha256 else {
                return Ok(candidate.clone());
            };
            match std::fs::read(candidate) {
                Ok(bytes) => {
                    let found = sha256_hex(&bytes);
                    if found == expected {
                        return Ok(candidate.clone());
                    }
                    other_content.push((candidate.clone(), found));
                }
                Err(_) => continue,
            }
        }
        Err(NotFound {
            tried: candidates,
            other_content,
        })
    }
}

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pinned_file_is_the_one_with_that_content() {
        let root = std::env::temp_dir().join(format!("cpmx-pinned-{}", std::process::id()));
        let (a, b) = (root.join("a"), root.join("b"));
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(a.join("map.xml"), "old").unwrap();
        std::fs::write(b.join("map.xml"), "new").unwrap();
        let data = DataPath::new(&a, std::slice::from_ref(&b), None);
        let new = sha256_hex(b"new");
        assert_eq!(
            data.find_pinned("map.xml", Some(&new)).unwrap(),
            b.join("map.xml")
        );
        assert_eq!(data.find_pinned("map.xml", None).unwrap(), a.join("map.xml"));
        let missing = data
            .find_pinned("map.xml", Some(&sha256_hex(b"other")))
            .unwrap_err();
        assert_eq!(missing.other_content.len(), 2);
        assert_eq!(missing.other_content[0], (a.join("map.xml"), sha256_hex(b"old")));
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn lists_every_place_it_looked() {
        let data = DataPath::new(
            Path::new("/nonexistent/spec"),
            &[PathBuf::from("/nonexistent/data")],
            Some("/a:/b"),
        );
        let tried = data.find("cpm.xml").unwrap_err();
        assert_eq!(tried.len(), 4);
        assert_eq!(tried[3], PathBuf::from("/b/cpm.xml"));
    }
}
