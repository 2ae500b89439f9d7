//! A campaign's directory: `plan.json` (what it runs), `runs/KEY.json` (one record per finished run, written then
//! renamed, so that a killed campaign leaves whole records or none), and the files made from them. A run whose
//! record is there is not run again.

use std::path::{Path, PathBuf};

use super::record::RunRecord;
use super::{CampaignError, PlanFile, RunSpec};

pub struct Store {
    pub dir: PathBuf,
}

impl Store {
    /// `dir` for `plan`: made if needed; a directory that holds another campaign's plan is refused.
    pub fn open(dir: &Path, plan: &PlanFile) -> Result<Store, CampaignError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| CampaignError::Io { path, source }
        };
        std::fs::create_dir_all(dir.join("runs")).map_err(io(dir))?;
        let path = dir.join("plan.json");
        match read_capped(&path) {
            Ok(text) => {
                let theirs = PlanFile::parse(&text).map_err(|message| CampaignError::Damaged {
                    path: path.clone(),
                    message,
                })?;
                if let Some(why) = theirs.differs(plan) {
                    return Err(CampaignError::OtherCampaign {
                        dir: dir.to_path_buf(),
                        why,
                    });
                }
            }
            Err(CampaignError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                write_atomic(&path, plan.to_json().as_bytes())?;
            }
            Err(e) => return Err(e),
        }
        Ok(Store { dir: dir.to_path_buf() })
    }

    fn record_path(&self, key: &str) -> PathBuf {
        self.dir.join("runs").join(format!("{key}.json"))
    }

    pub fn has(&self, key: &str) -> bool {
        self.record_path(key).is_file()
    }

    pub fn put(&self, r: &RunRecord) -> Result<(), CampaignError> {
        let json = serde_json::to_string_pretty(r).expect("a record always serialises");
        write_atomic(&self.record_path(&r.key), json.as_bytes())
    }

    /// The record of `run` of `plan`, if it is there: checked to be that run (its key, its seed and, where the
    /// record carries them, the swept values of the run's point by key), and filed under the point `plan` gives the
    /// run, whatever index the plan that wrote it used.
    pub fn get(&self, run: &RunSpec, plan: &PlanFile) -> Result<Option<RunRecord>, CampaignError> {
        let path = self.record_path(&run.key);
        if !path.is_file() {
            return Ok(None);
        }
        let text = read_capped(&path)?;
        let mut r: RunRecord = serde_json::from_str(&text).map_err(|e| CampaignError::Damaged {
            path: path.clone(),
            message: e.to_string(),
        })?;
        r.file_under(run, plan)
            .map_err(|message| CampaignError::Damaged { path, message })?;
        Ok(Some(r))
    }
}

/// [`simnet_engine::report::write_atomic`], its error naming the file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CampaignError> {
    simnet_engine::report::write_atomic(path, bytes).map_err(|source| CampaignError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// A campaign file's text ([`simnet_engine::input::read_text`]), its error naming the file.
pub fn read_capped(path: &Path) -> Result<String, CampaignError> {
    simnet_engine::input::read_text(path, simnet_engine::input::MAX_JSON).map_err(|source| CampaignError::Io {
        path: path.to_path_buf(),
        source,
    })
}
