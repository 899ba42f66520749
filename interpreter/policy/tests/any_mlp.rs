//! MLPs of any layer sizes from safetensors: sizes read from the file, relu/elu/tanh, the
//! output heads, and mis-shaped files reported with the tensor and both shapes.

use cpmx_policy::{Activation, ActorError, MlpActor, OutputHead};

/// Weights and biases of each layer.
type Layers = Vec<(Vec<f32>, Vec<f32>)>;

/// A safetensors file (8-byte header length, JSON header, little-endian f32 data) of an MLP
/// with layer `sizes`, its layers named `{prefix}.{index}`, weights from a fixed formula.
fn mlp_file(sizes: &[usize], prefix: &str, indices: &[usize]) -> (Vec<u8>, Layers) {
    let mut header = Vec::new();
    let mut data: Vec<u8> = Vec::new();
    let mut layers = Vec::new();
    for (l, (pair, index)) in sizes.windows(2).zip(indices).enumerate() {
        let (inputs, outputs) = (pair[0], pair[1]);
        let w: Vec<f32> = (0..inputs * outputs)
            .map(|i| ((i * 7 + l * 13) as f32 * 0.37).sin() / (inputs as f32).sqrt())
            .collect();
        let b: Vec<f32> = (0..outputs)
            .map(|j| ((j + l) as f32 * 0.21).cos() * 0.1)
            .collect();
        for (kind, values, shape) in [
            ("weight", &w, format!("[{outputs},{inputs}]")),
            ("bias", &b, format!("[{outputs}]")),
        ] {
            let start = data.len();
            data.extend(values.iter().flat_map(|v| v.to_le_bytes()));
            header.push(format!(
                "\"{prefix}.{index}.{kind}\":{{\"dtype\":\"F32\",\"shape\":{shape},\"data_offsets\":[{start},{}]}}",
                data.len()
            ));
        }
        layers.push((w, b));
    }
    let header = format!("{{{}}}", header.join(","));
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    (bytes, layers)
}

/// The forward pass in f64, for comparison.
fn naive(layers: &[(Vec<f32>, Vec<f32>)], x: &[f32], act: fn(f64) -> f64) -> Vec<f64> {
    let mut h: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
    for (l, (w, b)) in layers.iter().enumerate() {
        let inputs = h.len();
        let mut y: Vec<f64> = b
            .iter()
            .enumerate()
            .map(|(j, &bj)| {
                (0..inputs)
                    .map(|k| f64::from(w[j * inputs + k]) * h[k])
                    .sum::<f64>()
                    + f64::from(bj)
            })
            .collect();
        if l + 1 < layers.len() {
            y.iter_mut().for_each(|v| *v = act(*v));
        }
        h = y;
    }
    h
}

#[test]
fn a_32_64_64_64_4_relu_actor_runs_from_its_file() {
    let (bytes, layers) = mlp_file(&[32, 64, 64, 64, 4], "actor", &[0, 1, 2, 3]);
    let actor = MlpActor::from_bytes_any(&bytes, Activation::Relu).expect("loads");
    assert_eq!((actor.input_size(), actor.output_size()), (32, 4));
    assert_eq!(actor.weight_tensors()[2], ("actor.2.weight".to_owned(), [64, 64]));
    actor
        .check_fits(Some(32), OutputHead::SigmarlTanhNormal)
        .expect("fits");

    let agents = 5;
    let obs: Vec<f32> = (0..agents * 32).map(|i| (i as f32 * 0.13).sin()).collect();
    let mut raw = vec![0.0f32; agents * 4];
    let mut ws = actor.workspace(agents);
    actor.forward(&obs, &mut ws, &mut raw).expect("runs");
    for a in 0..agents {
        let want = naive(&layers, &obs[a * 32..(a + 1) * 32], |v| v.max(0.0));
        for (got, want) in raw[a * 4..(a + 1) * 4].iter().zip(want) {
            assert!((f64::from(*got) - want).abs() < 1e-5, "{got} vs {want}");
        }
    }
}

#[test]
fn torch_sequential_numbering_and_elu_with_a_deterministic_head() {
    // nn.Sequential(Linear, ELU, Linear, ELU, Linear): linear layers at 0, 2, 4.
    let (bytes, layers) = mlp_file(&[10, 24, 24, 2], "policy", &[0, 2, 4]);
    let actor = MlpActor::from_bytes_any(&bytes, Activation::Elu).expect("loads");
    actor
        .check_fits(Some(10), OutputHead::DeterministicTanh)
        .expect("fits");
    let obs: Vec<f32> = (0..10).map(|i| i as f32 * 0.3 - 1.5).collect();
    let mut raw = vec![0.0f32; 2];
    actor
        .forward(&obs, &mut actor.workspace(1), &mut raw)
        .expect("runs");
    let want = naive(&layers, &obs, |v| if v > 0.0 { v } else { v.exp_m1() });
    for (got, want) in raw.iter().zip(want) {
        assert!((f64::from(*got) - want).abs() < 1e-5);
    }
}

#[test]
fn mis_shaped_networks_name_the_tensor_and_the_shapes() {
    // Layers that do not chain: 32 -> 64, then a [64, 48] layer.
    let bytes = {
        let mut header = Vec::new();
        let mut data: Vec<u8> = Vec::new();
        for (name, shape) in [
            ("actor.0.weight", vec![64, 32]),
            ("actor.0.bias", vec![64]),
            ("actor.1.weight", vec![64, 48]),
            ("actor.1.bias", vec![64]),
        ] {
            let n: usize = shape.iter().product();
            let start = data.len();
            data.extend(std::iter::repeat_n(0u8, 4 * n));
            header.push(format!(
                "\"{name}\":{{\"dtype\":\"F32\",\"shape\":{shape:?},\"data_offsets\":[{start},{}]}}",
                data.len()
            ));
        }
        let header = format!("{{{}}}", header.join(","));
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend(header.as_bytes());
        bytes.extend(data);
        bytes
    };
    let e = MlpActor::from_bytes_any(&bytes, Activation::Relu).expect_err("does not chain");
    assert_eq!(
        e.to_string(),
        "tensor `actor.1.weight` has shape [64, 48], expected [64, 64]: its inputs must equal the 64 outputs of `actor.0.weight`"
    );

    // The first layer does not take the observation; the last does not feed the head.
    let (bytes, _) = mlp_file(&[30, 64, 4], "actor", &[0, 1]);
    let actor = MlpActor::from_bytes_any(&bytes, Activation::Tanh).expect("loads");
    let e = actor
        .check_fits(Some(32), OutputHead::SigmarlTanhNormal)
        .expect_err("input");
    assert!(matches!(e, ActorError::InputSize { .. }));
    assert_eq!(
        e.to_string(),
        "tensor `actor.0.weight` has shape [64, 30], expected [64, 32]: the first layer takes the observation's 32 values"
    );
    let e = actor
        .check_fits(Some(30), OutputHead::DeterministicClip)
        .expect_err("output");
    assert_eq!(
        e.to_string(),
        "tensor `actor.1.weight` has shape [4, 64], expected [2, 64]: the output head `deterministic-clip` reads 2 outputs (speed [m/s] and steering [rad])"
    );

    // No layers.
    let (mut bytes, _) = mlp_file(&[4, 4], "actor", &[0]);
    for i in 0..bytes.len() - 8 {
        if &bytes[i..i + 8] == b"actor.0." {
            bytes[i + 6] = b'x';
        }
    }
    let e = MlpActor::from_bytes_any(&bytes, Activation::Tanh).expect_err("no layers");
    assert!(matches!(e, ActorError::NoLayers { .. }), "{e}");
}
