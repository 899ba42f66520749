//! The learning curves of a `cpmx train` folder beside SigmaRL's, as one SVG (the README's
//! figure):
//!
//! ```sh
//! cargo run -p cpmx-train --example compare_curves -- [--column NAME] OUT.svg TRAIN_DIR... [SigmaRL *_data.json ...]
//! ```
//!
//! Each `TRAIN_DIR` is a `cpmx train` folder: every `<seed>/learning_curve.csv` in it is drawn,
//! and for a training in several fidelities every `<fidelity>/<seed>/learning_curve.csv`; or one
//! seed's folder, drawn alone (to set one training beside another's). `--column`
//! draws another column of the curves than `episode_reward_mean` (`collisions`, a reward term);
//! each JSON file is a SigmaRL checkpoint's `*_data.json` (its `episode_reward_mean_list`).

use std::path::{Path, PathBuf};

use cpmx_train::curve::{Series, column_points, column_svg};

fn main() -> Result<(), String> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let column = match args.iter().position(|a| a == "--column") {
        Some(at) if at + 1 < args.len() => {
            let column = args.remove(at + 1);
            args.remove(at);
            column
        }
        Some(_) => return Err("--column needs a column name".into()),
        None => "episode_reward_mean".to_owned(),
    };
    let usage = "usage: compare_curves [--column NAME] OUT.svg TRAIN_DIR... [SigmaRL *_data.json ...]";
    let [out, inputs @ ..] = args.as_slice() else {
        return Err(usage.into());
    };
    let (sigmarl, train_dirs): (Vec<&String>, Vec<&String>) =
        inputs.iter().partition(|a| a.ends_with(".json"));
    if train_dirs.is_empty() {
        return Err(usage.into());
    }
    if !sigmarl.is_empty() && column != "episode_reward_mean" {
        return Err("SigmaRL's checkpoints hold episode_reward_mean only".into());
    }
    let mut series = Vec::new();
    let mut folders = Vec::new();
    // Beside another training, a training's seeds are named by its folder too.
    let qualify = train_dirs.len() > 1;
    for train_dir in train_dirs {
        folders.extend(curve_folders(Path::new(train_dir), qualify)?);
    }
    for (label, dir) in folders {
        let text = std::fs::read_to_string(dir.join("learning_curve.csv")).map_err(|e| e.to_string())?;
        let points = column_points(&text, &column);
        if points.is_empty() {
            return Err(format!(
                "{}: no column `{column}`",
                dir.join("learning_curve.csv").display()
            ));
        }
        series.push(Series {
            // "cpmx" where SigmaRL's curves are drawn beside.
            name: if sigmarl.is_empty() {
                label
            } else {
                format!("cpmx {label}")
            },
            points,
        });
    }
    for file in &sigmarl {
        let text = std::fs::read_to_string(file).map_err(|e| format!("{file}: {e}"))?;
        let data: serde_json::Value = serde_json::from_str(&text).map_err(|e| format!("{file}: {e}"))?;
        let rewards = data["episode_reward_mean_list"]
            .as_array()
            .ok_or_else(|| format!("{file}: no episode_reward_mean_list"))?;
        // Named by the nearest folder of a seed: `seed2/checkpoint/*_data.json` (the reference
        // actors) or `seed2/*_data.json` (the paper's).
        let seed_folder = Path::new(file)
            .ancestors()
            .skip(1)
            .find(|dir| name(dir).starts_with("seed"))
            .unwrap_or(Path::new(file));
        series.push(Series {
            name: format!("SigmaRL {}", name(seed_folder)),
            points: rewards
                .iter()
                .enumerate()
                .filter_map(|(i, r)| Some(((i + 1) as f64, r.as_f64()?)))
                .collect(),
        });
    }
    let title = if sigmarl.is_empty() {
        format!("{column} per iteration")
    } else {
        format!("{column}: cpmx and SigmaRL")
    };
    std::fs::write(out, column_svg(&title, &column, &series)).map_err(|e| format!("{out}: {e}"))
}

/// The seed folders of a training folder with their legend labels (`seed 2`, or `sim-mpc
/// seed 2` for `<fidelity>/<seed>/`; with `qualify`, `<folder> seed 2`), sorted; a seed's
/// folder itself, labelled by its parent folder and its own (`twin-random seed 3`).
fn curve_folders(train_dir: &Path, qualify: bool) -> Result<Vec<(String, PathBuf)>, String> {
    if train_dir.join("learning_curve.csv").is_file() {
        let parent = train_dir.parent().map(name).unwrap_or_default();
        return Ok(vec![(
            format!("{parent} seed {}", name(train_dir)).trim().to_owned(),
            train_dir.to_owned(),
        )]);
    }
    let children = |dir: &Path| -> Result<Vec<PathBuf>, String> {
        let mut dirs: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| format!("{}: {e}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_dir())
            .collect();
        dirs.sort();
        Ok(dirs)
    };
    let mut folders = Vec::new();
    for child in children(train_dir)? {
        if child.join("learning_curve.csv").is_file() {
            let label = if qualify {
                format!("{} seed {}", name(train_dir), name(&child))
            } else {
                format!("seed {}", name(&child))
            };
            folders.push((label, child));
            continue;
        }
        for seed in children(&child)? {
            if seed.join("learning_curve.csv").is_file() {
                folders.push((format!("{} seed {}", name(&child), name(&seed)), seed));
            }
        }
    }
    if folders.is_empty() {
        return Err(format!(
            "{}: no learning_curve.csv in its seed folders",
            train_dir.display()
        ));
    }
    Ok(folders)
}

fn name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}
