//! Recorded IMU files named by a node's `imu_csv`, read while validating and checked against the run once the
//! overrides have set its duration and rate.

use std::path::Path;
use std::sync::Arc;

use super::{NodeConfig, Problem, RecordedImu, Scenario, ScenarioError, SimConfig, Validator};

impl Validator {
    /// Read `imu_csv`: relative to the topology file's folder, or to the working directory for a built-in.
    /// `[security]`: the key file read (relative to the topology file), or the run's own key from its seed when
    /// `auth` is set without a file.
    pub(crate) fn security(
        &mut self,
        raw: Option<&super::toml::RawSecurity>,
        topology_file: &str,
        seed: u64,
    ) -> super::SecurityConfig {
        let Some(raw) = raw else {
            return super::SecurityConfig::default();
        };
        if let Some(path) = &raw.key_file {
            let resolved = beside(topology_file, path);
            let shown = resolved.display().to_string();
            let key = crate::input::read_key(&resolved);
            return match key {
                Ok(k) => super::SecurityConfig {
                    key: Some(k),
                    key_source: Some(shown),
                },
                Err(m) => {
                    self.bad("security.key_file", m);
                    super::SecurityConfig::default()
                }
            };
        }
        if raw.auth == Some(true) {
            use sha2::Digest;
            let d = sha2::Sha256::digest(format!("simnet run key, seed {seed}").as_bytes());
            let mut k = [0u8; 16];
            k.copy_from_slice(&d[..16]);
            return super::SecurityConfig {
                key: Some(crate::wire::secure::Key::from_bytes(k)),
                key_source: Some("seed".into()),
            };
        }
        super::SecurityConfig::default()
    }

    pub(crate) fn recording(&mut self, key: &str, path: &str, topology_file: &str) -> Option<RecordedImu> {
        let resolved = beside(topology_file, path);
        let shown = resolved.display().to_string();
        if let Some(data) = self.loaded.get(&shown) {
            return Some(RecordedImu {
                given: path.to_string(),
                path: shown,
                data: data.clone(),
            });
        }
        let text = match crate::input::read_text(&resolved, crate::input::MAX_TABLE) {
            Ok(t) => t,
            Err(e) => {
                self.bad(key, format!("cannot read {shown}: {e}"));
                return None;
            }
        };
        match crate::imu_csv::parse(&text, &shown) {
            Ok(data) => {
                let data = Arc::new(data);
                self.loaded.insert(shown.clone(), data.clone());
                Some(RecordedImu {
                    given: path.to_string(),
                    path: shown,
                    data,
                })
            }
            Err(e) => {
                self.bad(key, e.to_string());
                None
            }
        }
    }
}

/// A recording that ends before the run does. Checked once the command-line overrides have set the duration and
/// the rate ([`Scenario::check_recordings`]); a node runs past the end of its file without IMU samples.
/// `path` as a topology file names it: relative to the file's folder.
fn beside(topology_file: &str, path: &str) -> std::path::PathBuf {
    let base = Path::new(topology_file);
    match base.parent() {
        Some(dir) if base.is_file() && Path::new(path).is_relative() => dir.join(path),
        _ => Path::new(path).to_path_buf(),
    }
}

fn recording_problems(sim: &SimConfig, nodes: &[NodeConfig]) -> Vec<Problem> {
    let need = sim.steps().saturating_sub(1) as f64 * sim.dt();
    nodes
        .iter()
        .enumerate()
        .filter_map(|(i, n)| {
            let r = n.recording.as_ref()?;
            let span = r.data.span();
            (span + 1e-6 * sim.dt() < need).then(|| Problem {
                key: format!("node[{i}].imu_csv"),
                message: format!(
                    "{} covers {span:.3} s, the run needs {need:.3} s (shorten sim.duration_s or --duration)",
                    r.path
                ),
            })
        })
        .collect()
}

impl Scenario {
    /// Every recorded IMU covers the run (checked by [`Scenario::with`] and before a run starts).
    pub fn check_recordings(&self) -> Result<(), ScenarioError> {
        let problems = recording_problems(&self.sim, &self.nodes);
        if problems.is_empty() {
            Ok(())
        } else {
            Err(ScenarioError::Invalid {
                file: self.source.clone(),
                problems,
            })
        }
    }
}
