//! The learning curves of a `cpmx train` folder beside SigmaRL's, as one SVG (the README's
//! figure):
//!
//! ```sh
//! cargo run -p cpmx-train --example compare_curves -- OUT.svg TRAIN_DIR [SigmaRL *_data.json ...]
//! ```
//!
//! `TRAIN_DIR` is a `cpmx train` folder (every `<seed>/learning_curve.csv` in it is drawn);
//! each JSON file is a SigmaRL checkpoint's `*_data.json` (its `episode_reward_mean_list`).

use std::path::{Path, PathBuf};

use cpmx_train::curve::{Series, reward_points, svg};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, train_dir, sigmarl @ ..] = args.as_slice() else {
        return Err("usage: compare_curves OUT.svg TRAIN_DIR [SigmaRL *_data.json ...]".into());
    };
    let mut series = Vec::new();
    let mut seeds: Vec<PathBuf> = std::fs::read_dir(train_dir)
        .map_err(|e| format!("{train_dir}: {e}"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("learning_curve.csv").is_file())
        .collect();
    seeds.sort();
    for dir in seeds {
        let text = std::fs::read_to_string(dir.join("learning_curve.csv")).map_err(|e| e.to_string())?;
        series.push(Series {
            name: format!("cpmx seed {}", name(&dir)),
            points: reward_points(&text),
        });
    }
    for file in sigmarl {
        let text = std::fs::read_to_string(file).map_err(|e| format!("{file}: {e}"))?;
        let data: serde_json::Value = serde_json::from_str(&text).map_err(|e| format!("{file}: {e}"))?;
        let rewards = data["episode_reward_mean_list"]
            .as_array()
            .ok_or_else(|| format!("{file}: no episode_reward_mean_list"))?;
        series.push(Series {
            name: format!(
                "SigmaRL {}",
                name(
                    Path::new(file)
                        .parent()
                        .and_then(Path::parent)
                        .unwrap_or(Path::new(file))
                )
            ),
            points: rewards
                .iter()
                .enumerate()
                .filter_map(|(i, r)| Some(((i + 1) as f64, r.as_f64()?)))
                .collect(),
        });
    }
    std::fs::write(out, svg("episode_reward_mean: cpmx and SigmaRL", &series))
        .map_err(|e| format!("{out}: {e}"))
}

fn name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}
