//! The data path: where a relative file named in a spec is looked for.
//!
//! In order: the spec's folder, each `--data DIR`, each folder of `CPMX_DATA`
//! (colon-separated). The first folder that has the file wins; when none has it, the error
//! lists every place that was tried.

use std::path::{Path, PathBuf};

/// The folders a relative file is looked up in, in order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DataPath {
    pub folders: Vec<PathBuf>,
}

impl DataPath {
    /// The data path of a spec in `spec_dir`, with `--data` folders and the `CPMX_DATA` value.
    pub fn new(spec_dir: &Path, data_dirs: &[PathBuf], cpmx_data: Option<&str>) -> Self {
        let mut folders = vec![spec_dir.to_path_buf()];
        folders.extend(data_dirs.iter().cloned());
        if let Some(var) = cpmx_data {
            folders.extend(var.split(':').filter(|s| !s.is_empty()).map(PathBuf::from));
        }
        Self { folders }
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

#[cfg(test)]
mod tests {
    use super::*;

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
