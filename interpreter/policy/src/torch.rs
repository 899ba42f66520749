//! PyTorch checkpoints as SigmaRL writes them: `torch.save` of an actor's state dict, a zip
//! archive (entries stored, not compressed, under one folder: `<name>/data.pkl`, the pickle,
//! `<name>/data/<k>`, the raw little-endian storages, `<name>/byteorder`, `<name>/version`).
//! The pickle is read by `pytorch-reader` (tracel-ai/burn's reader, which needs no Python); this
//! module checks the archive is what `torch.save` writes, so a damaged, truncated, re-packed or
//! foreign file is refused with what is wrong, and hands the float32 tensors on by name.

use std::path::Path;

use pytorch_reader::{DType, FileFormat, PytorchReader};

/// One tensor of a state dict: its name, shape and values (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct NamedTensor {
    pub name: String,
    pub shape: Vec<usize>,
    pub values: Vec<f32>,
}

/// The actor among a state dict's tensors as a safetensors file, as the conversion in
/// docs/policies.md writes it (`safetensors.torch.save_file`): its layers in order as
/// `actor.{i}.weight` and `actor.{i}.bias`, float32, no metadata. The same bytes, so a
/// converted file and the checkpoint are one actor to every tool.
pub fn to_safetensors(tensors: &[NamedTensor]) -> Result<Vec<u8>, crate::ActorError> {
    let layers = crate::layers::mlp_layers(tensors)?;
    let mut named: Vec<(String, safetensors::tensor::TensorView<'_>)> = Vec::new();
    let bytes: Vec<(Vec<u8>, Vec<u8>)> = layers
        .iter()
        .map(|l| {
            let le = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
            (le(&l.weight), le(&l.bias))
        })
        .collect();
    for (i, (layer, (weight, bias))) in layers.iter().zip(&bytes).enumerate() {
        named.push((
            format!("actor.{i}.weight"),
            f32_view(vec![layer.outputs, layer.inputs], weight)?,
        ));
        named.push((format!("actor.{i}.bias"), f32_view(vec![layer.outputs], bias)?));
    }
    safetensors::serialize(named, None).map_err(|e| crate::ActorError::Format(e.to_string()))
}

fn f32_view(
    shape: Vec<usize>,
    data: &[u8],
) -> Result<safetensors::tensor::TensorView<'_>, crate::ActorError> {
    safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape, data)
        .map_err(|e| crate::ActorError::Format(e.to_string()))
}

/// Why a file is not a state dict `torch.save` wrote.
#[derive(Debug, thiserror::Error)]
pub enum TorchError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Not a zip archive, or a damaged one (truncated: no end of its directory).
    #[error("{path} is not a PyTorch checkpoint (torch.save's zip archive): {reason}")]
    NotAnArchive {
        path: std::path::PathBuf,
        reason: String,
    },
    /// A zip archive, but not as `torch.save` writes it.
    #[error("{path} is not a checkpoint as torch.save writes it: {reason}")]
    Repacked {
        path: std::path::PathBuf,
        reason: String,
    },
    /// The archive's pickle or storages do not read.
    #[error("{path}: {reason}")]
    Content {
        path: std::path::PathBuf,
        reason: String,
    },
}

/// The float32 tensors of the state dict in the checkpoint at `path`, sorted by name.
/// Entries that are not tensors (SigmaRL's `__batch_size`, `__device`) are left out.
pub fn read_state_dict(path: &Path) -> Result<Vec<NamedTensor>, TorchError> {
    read_tensors(path, None)
}

/// The float32 tensors of the state dict saved under `key` of the dictionary in the
/// checkpoint at `path` (`torch.save({"model_state_dict": ..., ...})`), sorted by name.
pub fn read_state_dict_under(path: &Path, key: &str) -> Result<Vec<NamedTensor>, TorchError> {
    read_tensors(path, Some(key))
}

fn read_tensors(path: &Path, key: Option<&str>) -> Result<Vec<NamedTensor>, TorchError> {
    check_archive(path)?;
    let content = |reason: String| TorchError::Content {
        path: path.to_owned(),
        reason,
    };
    let reader = match key {
        None => PytorchReader::new(path),
        Some(key) => PytorchReader::with_top_level_key(path, key),
    }
    .map_err(|e| content(format!("its state dict does not read: {e}")))?;
    if !matches!(reader.metadata().format_type, FileFormat::Zip) {
        return Err(content("not torch.save's zip format".to_owned()));
    }
    let mut tensors = Vec::with_capacity(reader.len());
    for (name, tensor) in reader.tensors() {
        if tensor.dtype() != DType::F32 {
            return Err(content(format!(
                "tensor `{name}` holds {:?}, not float32 (SigmaRL's actors are float32)",
                tensor.dtype()
            )));
        }
        let bytes = tensor
            .read()
            .map_err(|e| content(format!("tensor `{name}` does not read: {e}")))?;
        if bytes.len() != tensor.byte_len() {
            return Err(content(format!(
                "tensor `{name}` of shape {:?} has {} bytes, expected {}",
                tensor.shape(),
                bytes.len(),
                tensor.byte_len()
            )));
        }
        let values: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        tensors.push(NamedTensor {
            name: name.clone(),
            shape: tensor.shape().to_vec(),
            values,
        });
    }
    tensors.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(tensors)
}

/// The NumPy `float32` scalar saved under `key` of the dictionary in the checkpoint at `path`
/// (SigmaRL's margin network keeps its `error_upper_bound` so). `pytorch-reader` does not
/// interpret NumPy scalars; their pickle is short and fixed (`numpy.core.multiarray.scalar`
/// of `dtype('f4')`, little-endian, with the four bytes as a latin-1 string through
/// `_codecs.encode`), so this reads exactly that and refuses anything else.
pub fn read_float32_scalar(path: &Path, key: &str) -> Result<f32, TorchError> {
    check_archive(path)?;
    let content = |reason: String| TorchError::Content {
        path: path.to_owned(),
        reason,
    };
    let io = |source| TorchError::Io {
        path: path.to_owned(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut archive = zip::ZipArchive::new(std::io::BufReader::new(file))
        .map_err(|e| content(format!("its archive does not read: {e}")))?;
    let name = archive
        .file_names()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| content(format!("its entries' names do not read: {e}")))?
        .into_iter()
        .find(|n| n.ends_with("/data.pkl"))
        .map(|n| n.into_owned())
        .ok_or_else(|| content("it has no `data.pkl`".to_owned()))?;
    let mut pickle = Vec::new();
    std::io::Read::read_to_end(
        &mut archive
            .by_name(&name)
            .map_err(|e| content(format!("`{name}` does not read: {e}")))?,
        &mut pickle,
    )
    .map_err(io)?;
    numpy_float32_after(&pickle, key).map_err(|reason| content(format!("`{key}`: {reason}")))
}

/// The `float32` of the NumPy scalar that follows the pickled string `key` in `pickle`.
fn numpy_float32_after(pickle: &[u8], key: &str) -> Result<f32, String> {
    let string = |text: &str| {
        let mut op = vec![b'X'];
        op.extend_from_slice(&(text.len() as u32).to_le_bytes());
        op.extend_from_slice(text.as_bytes());
        op
    };
    let find = |haystack: &[u8], needle: &[u8]| haystack.windows(needle.len()).position(|w| w == needle);
    let start = find(pickle, &string(key)).ok_or("no such key in the pickle")? + string(key).len();
    // The scalar's whole pickle is well under 200 bytes.
    let window = &pickle[start..pickle.len().min(start + 200)];
    let scalar = [
        b"numpy.core.multiarray\nscalar\n".as_slice(),
        b"numpy._core.multiarray\nscalar\n",
    ];
    if !scalar.iter().any(|s| find(window, s).is_some_and(|at| at < 8)) {
        return Err("not a NumPy scalar".to_owned());
    }
    if find(window, &string("f4")).is_none() || find(window, &string("<")).is_none() {
        return Err("not a little-endian float32 NumPy scalar".to_owned());
    }
    let encode = b"c_codecs\nencode\n";
    let at = find(window, encode).ok_or("its bytes are not pickled as `_codecs.encode`")? + encode.len();
    let rest = &window[at..];
    // An optional memo store (`q` + one byte, or `r` + four).
    let rest = match rest.first() {
        Some(b'q') => &rest[2.min(rest.len())..],
        Some(b'r') => &rest[5.min(rest.len())..],
        _ => rest,
    };
    let (&op, rest) = rest.split_first().ok_or("the pickle ends early")?;
    if op != b'X' || rest.len() < 4 {
        return Err("its bytes are not a string".to_owned());
    }
    let length = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
    let text = rest
        .get(4..4 + length)
        .and_then(|b| std::str::from_utf8(b).ok())
        .ok_or("its bytes are not a UTF-8 string")?;
    let bytes: Vec<u8> = text
        .chars()
        .map(|c| u8::try_from(u32::from(c)).map_err(|_| "its string is not latin-1".to_owned()))
        .collect::<Result<_, _>>()?;
    let bytes: [u8; 4] = bytes
        .try_into()
        .map_err(|b: Vec<u8>| format!("{} bytes, not the four of a float32", b.len()))?;
    Ok(f32::from_le_bytes(bytes))
}

/// The archive is one `torch.save` wrote: a zip whose entries lie under one folder with its
/// `data.pkl` and `version`, every entry stored uncompressed, the byte order little-endian.
fn check_archive(path: &Path) -> Result<(), TorchError> {
    let io = |source| TorchError::Io {
        path: path.to_owned(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let repacked = |reason: String| TorchError::Repacked {
        path: path.to_owned(),
        reason,
    };
    let mut archive =
        zip::ZipArchive::new(std::io::BufReader::new(file)).map_err(|e| TorchError::NotAnArchive {
            path: path.to_owned(),
            reason: match e {
                zip::result::ZipError::InvalidArchive(_) => {
                    format!("{e} (a truncated or damaged file, or no zip archive at all)")
                }
                other => other.to_string(),
            },
        })?;
    let names: Vec<String> = archive
        .file_names()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| repacked(format!("its entries' names do not read: {e}")))?
        .into_iter()
        .map(|n| n.into_owned())
        .collect();
    let Some(pickle) = names
        .iter()
        .find(|n| n.ends_with("/data.pkl") || *n == "data.pkl")
    else {
        return Err(repacked(
            "it has no `<name>/data.pkl` (a zip archive of something else, or a TorchScript file?)"
                .to_owned(),
        ));
    };
    let Some(root) = pickle.strip_suffix("data.pkl").filter(|r| !r.is_empty()) else {
        return Err(repacked(
            "its `data.pkl` is not inside a folder of the archive, where torch.save puts every entry (re-zipped?)"
                .to_owned(),
        ));
    };
    if let Some(outside) = names.iter().find(|n| !n.starts_with(root)) {
        return Err(repacked(format!(
            "entry `{outside}` lies outside the archive's folder `{root}` (re-zipped?)"
        )));
    }
    if !names
        .iter()
        .any(|n| *n == format!("{root}version") || *n == format!("{root}.data/version"))
    {
        return Err(repacked(format!("it has no `{root}version` entry (re-zipped?)")));
    }
    for index in 0..archive.len() {
        let entry = archive
            .by_index_raw(index)
            .map_err(|e| repacked(format!("entry {index} does not read: {e}")))?;
        if entry.compression() != zip::CompressionMethod::Stored {
            return Err(repacked(format!(
                "entry `{}` is compressed ({}); torch.save stores every entry uncompressed (re-zipped?)",
                entry.name().map(|n| n.into_owned()).unwrap_or_default(),
                entry.compression()
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("cpmx-torch-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_file_that_is_not_a_zip_archive_is_named_as_such() {
        let dir = scratch("foreign");
        let path = dir.join("actor_policy.pth");
        std::fs::write(&path, b"{\"not\": \"a checkpoint\"}").unwrap();
        let e = read_state_dict(&path).unwrap_err().to_string();
        assert!(
            e.contains("is not a PyTorch checkpoint (torch.save's zip archive)"),
            "{e}"
        );
        assert!(e.contains("actor_policy.pth"), "{e}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    /// SigmaRL's margin network of ECC 2025: its state dict under `model_state_dict` and its
    /// error bound, a NumPy scalar (0.012842575 in SigmaRL's `torch.load`).
    #[test]
    fn the_margin_networks_tensors_and_its_numpy_error_bound_read() {
        let path = cpmx_testdata::reference_file("sigmarl-published/checkpoints/ecc25/sm_predictor.pth");
        let tensors = read_state_dict_under(&path, "model_state_dict").unwrap();
        let shapes: Vec<(&str, &[usize])> = tensors
            .iter()
            .map(|t| (t.name.as_str(), t.shape.as_slice()))
            .collect();
        assert_eq!(
            shapes,
            [
                ("model.0.bias", [64].as_slice()),
                ("model.0.weight", &[64, 3]),
                ("model.2.bias", &[64]),
                ("model.2.weight", &[64, 64]),
                ("model.4.bias", &[1]),
                ("model.4.weight", &[1, 64]),
            ]
        );
        assert_eq!(
            read_float32_scalar(&path, "error_upper_bound").unwrap(),
            0.012842575
        );
        let e = read_float32_scalar(&path, "val_losses_history")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a NumPy scalar"), "{e}");
        let e = read_float32_scalar(&path, "no_such_key").unwrap_err().to_string();
        assert!(e.contains("no such key"), "{e}");
    }

    #[test]
    fn a_missing_file_says_so() {
        let e = read_state_dict(Path::new("/nonexistent/x_policy.pth"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("cannot read /nonexistent/x_policy.pth"), "{e}");
    }
}
