//! `cpmx validate SPEC...`: every problem of every spec, or one line per valid spec. A spec
//! with nothing but `cpmx`, `name`, `description` and `map` is answered with what the map
//! holds: lanelets, reference paths (ids, lengths, lanelets) and how they were numbered,
//! regions, bounds, and what the loader read but did not use.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cpmx_spec::model::MapSpec;
use cpmx_spec::{DataPath, SpecSource};
use cpmx_world::{Map, MapKind};

use super::{Failure, load_checked};
use crate::DataArgs;

pub fn run(specs: &[PathBuf], data: &DataArgs) -> Result<(), Failure> {
    let mut failed = false;
    for path in specs {
        if let Some(result) = map_only(path, data) {
            match result {
                Ok(summary) => print!("{summary}"),
                Err(message) => {
                    eprintln!("error: {}: {message}", path.display());
                    failed = true;
                }
            }
            continue;
        }
        match load_checked(path, data) {
            Ok(checked) => match checked.training_plan().len() {
                0 => println!("ok: {}: {} runs", path.display(), checked.plan().len()),
                trainings => println!(
                    "ok: {}: {} runs, {trainings} training runs",
                    path.display(),
                    checked.plan().len()
                ),
            },
            Err(_) => failed = true,
        }
    }
    if failed {
        Err(Failure::InvalidInput)
    } else {
        Ok(())
    }
}

/// The summary of a map-only spec, `None` when the spec is not one.
fn map_only(path: &Path, data: &DataArgs) -> Option<Result<String, String>> {
    let source = SpecSource::read(path).ok()?;
    let map_spec = cpmx_spec::map_only(&source)?;
    let cpmx_data = std::env::var("CPMX_DATA").ok();
    let data_path = DataPath::new(&source.dir, &data.data, cpmx_data.as_deref());
    let file = match &map_spec {
        MapSpec::File(f) => match data_path.find(&f.file) {
            Ok(found) => Some(found),
            Err(tried) => {
                let tried: Vec<String> = tried.iter().map(|p| p.display().to_string()).collect();
                return Some(Err(format!(
                    "map file `{}` not found (looked in: {})",
                    f.file,
                    tried.join(", ")
                )));
            }
        },
        MapSpec::Sigmarl(m) => match data_path.find(m.table_file()) {
            Ok(found) => Some(found),
            Err(tried) => {
                let tried: Vec<String> = tried.iter().map(|p| p.display().to_string()).collect();
                return Some(Err(format!(
                    "SigmaRL's scenario table `{}` not found (looked in: {})",
                    m.table_file(),
                    tried.join(", ")
                )));
            }
        },
        MapSpec::Builtin(_) => None,
    };
    Some(
        cpmx_engine::load_map_spec(&map_spec, file.as_deref())
            .map(|map| {
                let name = match (&map_spec, &file) {
                    (MapSpec::Sigmarl(m), _) => format!("SigmaRL's scenario `{}`", m.sigmarl),
                    (_, Some(file)) => file.display().to_string(),
                    (MapSpec::Builtin(name), None) => name.clone(),
                    (MapSpec::File(f), None) => f.file.clone(),
                };
                summary(path, &name, &map)
            })
            .map_err(|e| e.to_string()),
    )
}

/// What a map holds, for a person choosing `ref_path` ids.
fn summary(spec: &Path, name: &str, map: &Map) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "ok: {}: map-only spec; the map {name} holds:", spec.display());
    // SigmaRL's scenario maps have one-way lanes only.
    let reverse = if map.kind() == MapKind::SigmarlScenario {
        ""
    } else {
        " (the reverse of a two-way lanelet N is lanelet -N-1)"
    };
    let _ = writeln!(s, "  lanelets: {}{reverse}", map.lanelets().count());
    let b = map.bounds();
    let _ = writeln!(
        s,
        "  bounds: x {:.3} .. {:.3} m, y {:.3} .. {:.3} m ({:.1} m x {:.1} m)",
        b.min_x_m,
        b.max_x_m,
        b.min_y_m,
        b.max_y_m,
        b.max_x_m - b.min_x_m,
        b.max_y_m - b.min_y_m
    );
    let regions: Vec<&str> = map.region_names().collect();
    let _ = writeln!(
        s,
        "  regions (map: {{region: NAME}}): {}",
        if regions.is_empty() {
            "none".to_owned()
        } else {
            regions.join(", ")
        }
    );
    for note in map.notes() {
        let _ = writeln!(s, "  note: {note}");
    }
    let numbering = match map.kind() {
        MapKind::CpmLab => "SigmaRL's numbering of the CPM Lab map (cpm_entire: 40 loops)".to_owned(),
        MapKind::Builtin(name) => format!("the built-in map `{name}`'s own numbering"),
        MapKind::SigmarlScenario => "SigmaRL's scenario table (paths by their position in it)".to_owned(),
        MapKind::Generic => format!(
            "generic numbering: first every chain of successors from a lanelet without \
             predecessors (starts by ascending id, branches by ascending id), then every loop from \
             its lowest lanelet id (at most {} of these), then a walk from every lanelet on no path \
             yet over its lowest-id successors; chains whose boundaries do not line up are skipped \
             and keep their number unused",
            cpmx_world::generic::MAX_GENERIC_PATHS
        ),
    };
    let paths: Vec<_> = map.reference_paths().collect();
    let _ = writeln!(s, "  reference paths (ref_path): {}, by {numbering}", paths.len());
    for p in paths {
        let ids: Vec<String> = p.lanelet_ids.iter().map(ToString::to_string).collect();
        let _ = writeln!(
            s,
            "    {}: {:.2} m, {}, lanelets {}",
            p.id,
            p.center_line.length_m(),
            if p.is_loop { "loop" } else { "open" },
            ids.join(" -> ")
        );
    }
    s
}
