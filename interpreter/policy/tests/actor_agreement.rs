//! Agreement of the MLP actor and its output mapping with SigmaRL's own `ProbabilisticActor`
//! (`shared/reference/policy/actor_layout.json`, 36 test vectors), and loading errors.

mod common;

use common::{json, max_abs_diff, nums, reference_file};
use cpmx_policy::{ActionHead, ActionMode, ActorError, MlpActor, MlpLayout};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// Agreement with torch's float32 outputs. cpmx sums each of a layer's 256 products in one
/// running sum of fused multiply-adds (`cpmx-kernels`, the trainer's arithmetic), torch in
/// blocks: on the 36 vectors the raw outputs differ by up to 1.7e-6, cpmx's being 1.4e-6 from
/// the exact network and torch's 6.0e-7 (each within a few float32 ulps of outputs up to 5).
const TOLERANCE: f64 = 3e-6;
/// Largest distance of the float32 forward pass from the float64 network.
const EXACT_TOLERANCE: f64 = 2e-6;

fn weights() -> std::path::PathBuf {
    reference_file("policy/actor.safetensors")
}

#[test]
fn actor_matches_all_36_test_vectors() {
    let actor = MlpActor::load(&weights(), &MlpLayout::sigmarl()).unwrap();
    assert_eq!(actor.input_size(), 32);
    let layout = json("policy/actor_layout.json");
    let vectors = layout["test_vectors"].as_array().unwrap();
    assert_eq!(vectors.len(), 36);

    // One batched forward pass over all 36 observations.
    let obs: Vec<f32> = vectors
        .iter()
        .flat_map(|v| nums(&v["obs"]))
        .map(|x| x as f32)
        .collect();
    let mut ws = actor.workspace(vectors.len());
    let mut raw = vec![0.0f32; vectors.len() * 4];
    actor.forward(&obs, &mut ws, &mut raw).unwrap();

    let head = ActionHead::default();
    let mut rng = ChaCha20Rng::seed_from_u64(0);
    let mut worst = [0.0f64; 4];
    for (i, v) in vectors.iter().enumerate() {
        let r: [f32; 4] = raw[i * 4..i * 4 + 4].try_into().unwrap();
        let out = head.map(&r, ActionMode::Mean, &mut rng);
        let widen = |s: &[f32]| s.iter().map(|&x| f64::from(x)).collect::<Vec<_>>();
        let errs = [
            max_abs_diff(&widen(&r), &nums(&v["raw_output"])),
            max_abs_diff(&widen(&out.loc), &nums(&v["loc"])),
            max_abs_diff(&widen(&out.scale), &nums(&v["scale"])),
            max_abs_diff(&widen(&out.action), &nums(&v["action_deterministic"])),
        ];
        for (w, e) in worst.iter_mut().zip(errs) {
            *w = w.max(e);
        }
    }
    eprintln!("actor max abs errors raw/loc/scale/action: {worst:?}");
    assert!(worst.iter().all(|&e| e <= TOLERANCE), "{worst:?}");

    // Both float32 evaluations against the exact network (float64 from the same weights):
    // cpmx's running FMA sums are as close to it as torch's blocked sums.
    let exact = exact_forward(&std::fs::read(weights()).unwrap(), &obs, vectors.len());
    let torch: Vec<f64> = vectors.iter().flat_map(|v| nums(&v["raw_output"])).collect();
    let ours: Vec<f64> = raw.iter().map(|&x| f64::from(x)).collect();
    let (ours_error, torch_error) = (max_abs_diff(&ours, &exact), max_abs_diff(&torch, &exact));
    eprintln!("from the exact network: cpmx {ours_error:e}, torch {torch_error:e}");
    assert!(
        ours_error <= EXACT_TOLERANCE,
        "cpmx {ours_error:e}, torch {torch_error:e}"
    );
}

/// SigmaRL's actor in float64 (tanh after every layer but the last) over `rows` observations.
fn exact_forward(bytes: &[u8], obs: &[f32], rows: usize) -> Vec<f64> {
    let tensors = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let read = |name: String| -> Vec<f64> {
        let view = tensors.tensor(&name).unwrap();
        view.data()
            .chunks_exact(4)
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect()
    };
    let mut h: Vec<f64> = obs.iter().map(|&x| f64::from(x)).collect();
    let mut width = obs.len() / rows;
    for l in 0..4 {
        let (w, b) = (read(format!("actor.{l}.weight")), read(format!("actor.{l}.bias")));
        let outputs = b.len();
        let mut next = vec![0.0; rows * outputs];
        for r in 0..rows {
            for j in 0..outputs {
                let z: f64 = (0..width)
                    .map(|k| h[r * width + k] * w[j * width + k])
                    .sum::<f64>()
                    + b[j];
                next[r * outputs + j] = if l < 3 { z.tanh() } else { z };
            }
        }
        (h, width) = (next, outputs);
    }
    h
}

#[test]
fn batch_size_does_not_change_results() {
    let actor = MlpActor::load(&weights(), &MlpLayout::sigmarl()).unwrap();
    let layout = json("policy/actor_layout.json");
    let obs: Vec<f32> = layout["test_vectors"].as_array().unwrap()[..5]
        .iter()
        .flat_map(|v| nums(&v["obs"]))
        .map(|x| x as f32)
        .collect();
    let mut ws = actor.workspace(5);
    let mut all = vec![0.0f32; 20];
    actor.forward(&obs, &mut ws, &mut all).unwrap();
    for a in 0..5 {
        let mut one = [0.0f32; 4];
        actor
            .forward(&obs[a * 32..(a + 1) * 32], &mut ws, &mut one)
            .unwrap();
        assert_eq!(one[..], all[a * 4..a * 4 + 4]);
    }
}

#[test]
fn sampling_is_reproducible_from_a_seed() {
    let head = ActionHead::default();
    let raw = [0.3f32, -0.2, -1.0, -1.5];
    let draw = |seed| {
        let mut rng = ChaCha20Rng::seed_from_u64(seed);
        (0..10)
            .map(|_| head.map(&raw, ActionMode::Sample, &mut rng).action)
            .collect::<Vec<_>>()
    };
    assert_eq!(draw(7), draw(7));
    assert_ne!(draw(7), draw(8));
    // The mean is unaffected by the draws.
    let mut rng = ChaCha20Rng::seed_from_u64(7);
    let mean = head.map(&raw, ActionMode::Mean, &mut rng).action;
    assert!((mean[0] - 0.3f32.tanh()).abs() < 1e-6);
}

#[test]
fn wrong_shapes_and_missing_tensors_are_typed_errors() {
    let bytes = std::fs::read(weights()).unwrap();
    let mut layout = MlpLayout::sigmarl();
    layout.input_size = 30;
    match MlpActor::from_bytes(&bytes, &layout) {
        Err(ActorError::Shape {
            name,
            expected,
            found,
        }) => {
            assert_eq!(name, "actor.0.weight");
            assert_eq!(expected, vec![256, 30]);
            assert_eq!(found, vec![256, 32]);
        }
        other => panic!("{other:?}"),
    }
    let mut layout = MlpLayout::sigmarl();
    layout.hidden_sizes.push(256);
    match MlpActor::from_bytes(&bytes, &layout) {
        Err(ActorError::Shape { name, .. }) => assert_eq!(name, "actor.3.weight"),
        other => panic!("{other:?}"),
    }
    let mut layout = MlpLayout::sigmarl();
    layout.prefix = "critic".into();
    match MlpActor::from_bytes(&bytes, &layout) {
        Err(err @ ActorError::MissingTensor { .. }) => {
            assert_eq!(
                err.to_string(),
                "tensor `critic.0.weight` is missing (expected shape [256, 32])"
            )
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        MlpActor::from_bytes(b"nonsense", &MlpLayout::sigmarl()),
        Err(ActorError::Format(_))
    ));
}

#[test]
fn a_float64_tensor_is_a_dtype_error() {
    // A one-tensor safetensors file: 8-byte header length, JSON header, data.
    let header = r#"{"actor.0.weight":{"dtype":"F64","shape":[256,32],"data_offsets":[0,65536]}}"#;
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend(header.as_bytes());
    bytes.extend(vec![0u8; 65536]);
    match MlpActor::from_bytes(&bytes, &MlpLayout::sigmarl()) {
        Err(ActorError::Dtype { name, found }) => {
            assert_eq!((name.as_str(), found.as_str()), ("actor.0.weight", "F64"))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_layout_is_read_from_the_weights() {
    let bytes = std::fs::read(weights()).unwrap();
    assert_eq!(
        MlpLayout::from_safetensors(&bytes, "actor").unwrap(),
        MlpLayout::sigmarl()
    );
    // The reference critic: 128 -> 256 x 3 -> 1.
    let critic = std::fs::read(reference_file("training/critic.safetensors")).unwrap();
    let layout = MlpLayout::from_safetensors(&critic, "critic").unwrap();
    assert_eq!(layout.sizes(), [128, 256, 256, 256, 1]);
    assert!(matches!(
        MlpLayout::from_safetensors(&bytes, "critic"),
        Err(ActorError::MissingTensor { .. })
    ));
    // Loading with the inferred layout gives the same network.
    let inferred = MlpActor::load_inferred(&weights(), "actor").unwrap();
    assert_eq!(
        inferred,
        MlpActor::load(&weights(), &MlpLayout::sigmarl()).unwrap()
    );
}
