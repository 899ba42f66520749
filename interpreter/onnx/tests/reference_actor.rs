//! SigmaRL's reference actor (`shared/reference/policy/actor.safetensors`) written as ONNX by
//! the test (Gemm and MatMul + Add graphs) is read as an MLP that gives bit for bit the
//! safetensors actor's outputs on cpmx's kernels, and run by tract agrees with it on every reference observation (697
//! agent-steps and the 36 test vectors), raw outputs and actions; graphs that do not fit are
//! refused naming their shapes.

use std::path::PathBuf;

use cpmx_onnx::{Activation, Batch, LinearStyle, OnnxActor, OnnxError, OutputHead, mlp_to_onnx};
use cpmx_policy::{ActionHead, ActionMode, MlpActor, Network};
use prost::Message;
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// Largest difference allowed between the two runtimes (float32 sums in another order, and
/// tract's own tanh).
const TOLERANCE: f32 = 1e-5;

fn reference(file: &str) -> PathBuf {
    cpmx_testdata::reference_file(file)
}

fn json(file: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(reference(file)).unwrap()).unwrap()
}

fn floats(v: &serde_json::Value) -> Vec<f32> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect()
}

/// Every reference observation, grouped as the steps that produced them (1..=n agents each).
fn observation_groups() -> Vec<Vec<f32>> {
    let mut groups = Vec::new();
    for episode in json("observations/obs_cases.json")["episodes"]
        .as_array()
        .unwrap()
    {
        for step in episode["steps"].as_array().unwrap() {
            let group: Vec<f32> = step["agents"]
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|a| floats(&a["obs"]))
                .collect();
            groups.push(group);
        }
    }
    groups
}

fn reference_weights() -> Vec<u8> {
    std::fs::read(reference("policy/actor.safetensors")).unwrap()
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

/// Raw outputs of the safetensors actor on cpmx's kernels.
fn mlp_raw(actor: &MlpActor, observations: &[f32]) -> Vec<f32> {
    let agents = observations.len() / actor.input_size();
    let mut ws = actor.workspace(agents);
    let mut raw = vec![0.0; agents * actor.output_size()];
    actor.forward(observations, &mut ws, &mut raw).unwrap();
    raw
}

fn onnx_raw(actor: &OnnxActor, observations: &[f32]) -> Vec<f32> {
    let mut raw = vec![0.0; observations.len() / actor.input_size() * actor.output_size()];
    actor.forward(observations, &mut raw).unwrap();
    raw
}

/// Mean actions of SigmaRL's head for raw outputs.
fn actions(raw: &[f32]) -> Vec<f32> {
    let mut rng = ChaCha20Rng::seed_from_u64(0);
    raw.chunks_exact(4)
        .flat_map(|r| {
            OutputHead::SigmarlTanhNormal
                .map(&ActionHead::default(), r, ActionMode::Mean, &mut rng)
                .action
        })
        .collect()
}

#[test]
fn the_reference_actor_as_onnx_agrees_with_the_safetensors_actor() {
    let weights = reference_weights();
    let mlp = MlpActor::from_bytes_any(&weights, Activation::Tanh).unwrap();
    let groups = observation_groups();
    assert_eq!(groups.iter().map(|g| g.len() / 32).sum::<usize>(), 697);
    let vectors = json("policy/actor_layout.json")["test_vectors"]
        .as_array()
        .unwrap()
        .clone();

    for style in [LinearStyle::Gemm, LinearStyle::MatMulAdd] {
        let bytes = mlp_to_onnx(&weights, Activation::Tanh, style).unwrap();
        let onnx = OnnxActor::from_bytes(&bytes, None, None).unwrap();
        let lowered = onnx
            .as_mlp()
            .unwrap_or_else(|| panic!("{style:?} is a plain MLP"));
        let all: Vec<f32> = groups.concat();
        assert_eq!(
            mlp_raw(&mlp, &all),
            mlp_raw(lowered, &all),
            "{style:?}: bit for bit"
        );
        assert_eq!(onnx.batch(), Batch::Symbolic);
        assert_eq!(onnx.input().1.to_string(), "[batch, 32]");
        assert_eq!(onnx.output().1.to_string(), "[batch, 4]");
        onnx.check_fits(32, OutputHead::SigmarlTanhNormal).unwrap();

        // Step by step (batches of the agents of a step) and all 697 at once.
        let (mut worst_raw, mut worst_action) = (0.0f32, 0.0f32);
        for group in &groups {
            let (a, b) = (mlp_raw(&mlp, group), onnx_raw(&onnx, group));
            worst_raw = worst_raw.max(max_diff(&a, &b));
            worst_action = worst_action.max(max_diff(&actions(&a), &actions(&b)));
        }
        worst_raw = worst_raw.max(max_diff(&mlp_raw(&mlp, &all), &onnx_raw(&onnx, &all)));
        assert!(
            worst_raw < TOLERANCE,
            "{style:?}: raw outputs differ by {worst_raw}"
        );
        assert!(
            worst_action < TOLERANCE,
            "{style:?}: actions differ by {worst_action}"
        );

        // SigmaRL's own outputs for the 36 test vectors.
        for (k, v) in vectors.iter().enumerate() {
            let raw = onnx_raw(&onnx, &floats(&v["obs"]));
            let d = max_diff(&raw, &floats(&v["raw_output"]));
            assert!(
                d < TOLERANCE,
                "{style:?}: test vector {k} differs from SigmaRL by {d}"
            );
            let d = max_diff(&actions(&raw), &floats(&v["action_deterministic"]));
            assert!(
                d < TOLERANCE,
                "{style:?}: test vector {k}'s action differs from SigmaRL by {d}"
            );
        }
        eprintln!("{style:?}: raw outputs within {worst_raw:e}, actions within {worst_action:e}");
    }
}

/// A small MLP as safetensors (`net.N.weight`, `net.N.bias`).
fn small_mlp(sizes: &[usize]) -> Vec<u8> {
    let mut header = Vec::new();
    let mut data: Vec<u8> = Vec::new();
    for (l, pair) in sizes.windows(2).enumerate() {
        let (inputs, outputs) = (pair[0], pair[1]);
        let w: Vec<f32> = (0..inputs * outputs)
            .map(|i| ((i * 7 + l) as f32 * 0.37).sin() / (inputs as f32).sqrt())
            .collect();
        let b: Vec<f32> = (0..outputs).map(|j| (j as f32 * 0.21).cos() * 0.05).collect();
        for (kind, values, shape) in [
            ("weight", w, format!("[{outputs},{inputs}]")),
            ("bias", b, format!("[{outputs}]")),
        ] {
            let start = data.len();
            data.extend(values.iter().flat_map(|v| v.to_le_bytes()));
            header.push(format!(
                "\"net.{l}.{kind}\":{{\"dtype\":\"F32\",\"shape\":{shape},\"data_offsets\":[{start},{}]}}",
                data.len()
            ));
        }
    }
    let header = format!("{{{}}}", header.join(","));
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    bytes
}

#[test]
fn relu_and_elu_networks_of_other_sizes_agree_and_a_unit_batch_runs_agent_by_agent() {
    let observations: Vec<f32> = (0..5 * 20).map(|i| (i as f32 * 0.13).sin()).collect();
    for activation in [Activation::Relu, Activation::Elu] {
        let weights = small_mlp(&[20, 24, 16, 2]);
        let mlp = MlpActor::from_bytes_any(&weights, activation).unwrap();
        let bytes = mlp_to_onnx(&weights, activation, LinearStyle::Gemm).unwrap();
        let onnx = OnnxActor::from_bytes(&bytes, Some("observation"), Some("raw")).unwrap();
        let lowered = onnx.as_mlp().expect("a plain MLP");
        assert_eq!(mlp_raw(&mlp, &observations), mlp_raw(lowered, &observations));
        onnx.check_fits(20, OutputHead::DeterministicTanh).unwrap();
        let d = max_diff(&mlp_raw(&mlp, &observations), &onnx_raw(&onnx, &observations));
        assert!(d < TOLERANCE, "{activation:?}: {d}");

        // The same graph exported with a batch fixed at 1 runs one agent at a time.
        let mut model = tract_onnx::pb::ModelProto::decode(&bytes[..]).unwrap();
        let graph = model.graph.as_mut().unwrap();
        for value in graph.input.iter_mut().chain(graph.output.iter_mut()) {
            set_first_dim(value, 1);
        }
        let unit = OnnxActor::from_bytes(&model.encode_to_vec(), None, None).unwrap();
        assert_eq!(unit.batch(), Batch::One);
        let d = max_diff(&onnx_raw(&onnx, &observations), &onnx_raw(&unit, &observations));
        assert!(d < TOLERANCE, "{activation:?} unit batch: {d}");
    }
}

fn set_first_dim(value: &mut tract_onnx::pb::ValueInfoProto, size: i64) {
    use tract_onnx::pb::tensor_shape_proto::dimension::Value;
    use tract_onnx::pb::type_proto;
    let Some(type_proto::Value::TensorType(t)) = value.r#type.as_mut().and_then(|t| t.value.as_mut()) else {
        panic!("a tensor type")
    };
    t.shape.as_mut().unwrap().dim[0].value = Some(Value::DimValue(size));
}

#[test]
fn graphs_that_do_not_fit_are_refused_naming_their_shapes() {
    let weights = small_mlp(&[33, 8, 3]);
    let bytes = mlp_to_onnx(&weights, Activation::Tanh, LinearStyle::Gemm).unwrap();
    let onnx = OnnxActor::from_bytes(&bytes, None, None).unwrap();
    let e = onnx.check_fits(32, OutputHead::SigmarlTanhNormal).unwrap_err();
    assert!(matches!(e, OnnxError::InputSize { .. }));
    assert_eq!(
        e.to_string(),
        "input `observation` has shape [batch, 33], the observation has 32 values"
    );
    let e = onnx.check_fits(33, OutputHead::SigmarlTanhNormal).unwrap_err();
    assert_eq!(
        e.to_string(),
        "output `raw` has shape [batch, 3], 3 values per agent; the output head `sigmarl-tanh-normal` reads 4 \
         (2 locations and 2 pre-scales of a TanhNormal)"
    );

    // Names that the graph lacks, a batch fixed above 1, and bytes that are not ONNX.
    let e = OnnxActor::from_bytes(&bytes, Some("obs"), None).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the graph has no input `obs`; its inputs: observation"
    );
    let e = OnnxActor::from_bytes(&bytes, None, Some("action")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the graph has no output `action`; its outputs: raw"
    );
    let mut model = tract_onnx::pb::ModelProto::decode(&bytes[..]).unwrap();
    let graph = model.graph.as_mut().unwrap();
    set_first_dim(&mut graph.input[0], 8);
    let e = OnnxActor::from_bytes(&model.encode_to_vec(), None, None).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("input `observation` has shape [8, 33]; its batch is fixed at 8"),
        "{e}"
    );
    let e = OnnxActor::from_bytes(b"not a protobuf at all", None, None).unwrap_err();
    assert!(matches!(e, OnnxError::Format(_)), "{e}");
}

/// Graphs as PyTorch's exporters also write them still run on cpmx's kernels bit for bit: the
/// weights as `Transpose` of an initializer before `MatMul` (torch.export's `aten::linear`), and
/// an `Identity` on the chain. A graph that is not a plain chain (the input also read by another
/// node) runs on tract.
#[test]
fn pytorch_style_graphs_are_lowered_and_branching_ones_are_not() {
    let observations: Vec<f32> = (0..3 * 20).map(|i| (i as f32 * 0.29).cos()).collect();
    let weights = small_mlp(&[20, 24, 16, 4]);
    let mlp = MlpActor::from_bytes_any(&weights, Activation::Tanh).unwrap();
    let bytes = mlp_to_onnx(&weights, Activation::Tanh, LinearStyle::MatMulAdd).unwrap();
    let model = tract_onnx::pb::ModelProto::decode(&bytes[..]).unwrap();

    // Every MatMul weight [in, out] becomes Transpose(torch's [out, in]); an Identity follows
    // the first activation.
    let mut torch_style = model.clone();
    let graph = torch_style.graph.as_mut().unwrap();
    let matmuls: Vec<usize> = (0..graph.node.len())
        .filter(|&i| graph.node[i].op_type == "MatMul")
        .collect();
    for &i in matmuls.iter().rev() {
        let weight_name = graph.node[i].input[1].clone();
        let init = graph
            .initializer
            .iter_mut()
            .find(|t| t.name == weight_name)
            .unwrap();
        let (rows, cols) = (init.dims[0] as usize, init.dims[1] as usize);
        let values: Vec<f32> = init
            .raw_data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let mut transposed = vec![0.0f32; values.len()];
        for r in 0..rows {
            for c in 0..cols {
                transposed[c * rows + r] = values[r * cols + c];
            }
        }
        init.name = format!("{weight_name}.torch");
        init.dims = vec![cols as i64, rows as i64];
        init.raw_data = transposed.iter().flat_map(|v| v.to_le_bytes()).collect();
        let transpose = tract_onnx::pb::NodeProto {
            name: format!("{weight_name}.transpose"),
            op_type: "Transpose".into(),
            input: vec![init.name.clone()],
            output: vec![weight_name],
            ..Default::default()
        };
        graph.node.insert(i, transpose);
    }
    let tanh = graph.node.iter().position(|n| n.op_type == "Tanh").unwrap();
    let tanh_out = graph.node[tanh].output[0].clone();
    for n in graph.node.iter_mut() {
        for input in n.input.iter_mut().filter(|i| **i == tanh_out) {
            *input = format!("{tanh_out}.identity");
        }
    }
    graph.node.insert(
        tanh + 1,
        tract_onnx::pb::NodeProto {
            name: "identity".into(),
            op_type: "Identity".into(),
            input: vec![tanh_out.clone()],
            output: vec![format!("{tanh_out}.identity")],
            ..Default::default()
        },
    );
    let torch_style = OnnxActor::from_bytes(&torch_style.encode_to_vec(), None, None).unwrap();
    let lowered = torch_style.as_mlp().expect("lowered");
    assert_eq!(mlp_raw(&mlp, &observations), mlp_raw(lowered, &observations));

    // The input read twice (a second output that tract drops): not a plain chain.
    let mut branching = model;
    let graph = branching.graph.as_mut().unwrap();
    let input = graph.input[0].name.clone();
    graph.node.push(tract_onnx::pb::NodeProto {
        name: "side".into(),
        op_type: "Relu".into(),
        input: vec![input],
        output: vec!["side".into()],
        ..Default::default()
    });
    let on_tract = OnnxActor::from_bytes(&branching.encode_to_vec(), None, None).unwrap();
    assert!(on_tract.as_mlp().is_none());
    let d = max_diff(&mlp_raw(&mlp, &observations), &onnx_raw(&on_tract, &observations));
    assert!(d < TOLERANCE, "{d}");
}
