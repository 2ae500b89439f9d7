//! Names → paths → built-ins: a path, then `./topologies/NAME.toml`, then the copies compiled into the binary
//! ([`super::builtin`]). The only place a topology file is read.

use std::path::Path;

use super::{builtin, Scenario, ScenarioError};

/// `./topologies/NAME.toml`, without doubling an extension the user gave.
pub(crate) fn in_topologies(name: &str) -> String {
    if name.ends_with(".toml") {
        format!("./topologies/{name}")
    } else {
        format!("./topologies/{name}.toml")
    }
}

impl Scenario {
    pub fn from_path(path: &Path) -> Result<Scenario, ScenarioError> {
        let file = path.display().to_string();
        let text = crate::input::read_text(path, crate::input::MAX_TOPOLOGY).map_err(|source| ScenarioError::Io {
            file: file.clone(),
            source,
        })?;
        Scenario::from_toml(&text, &file)
    }

    /// A path, then `./topologies/NAME.toml`, then a built-in.
    pub fn resolve(name_or_path: &str) -> Result<Scenario, ScenarioError> {
        let (text, file) = Scenario::resolve_text(name_or_path)?;
        Scenario::from_toml(&text, &file)
    }

    /// The TOML text [`Scenario::resolve`] would parse, and the name it gives the file in errors.
    pub fn resolve_text(name_or_path: &str) -> Result<(String, String), ScenarioError> {
        let read = |p: &Path| {
            let file = p.display().to_string();
            crate::input::read_text(p, crate::input::MAX_TOPOLOGY)
                .map(|t| (t, file.clone()))
                .map_err(|source| ScenarioError::Io { file, source })
        };
        let p = Path::new(name_or_path);
        if p.is_file() {
            return read(p);
        }
        let local = Path::new("topologies").join(format!("{name_or_path}.toml"));
        if local.is_file() {
            return read(&local);
        }
        match builtin::get(name_or_path) {
            Some(text) => Ok((text.to_string(), format!("builtin:{name_or_path}"))),
            None => Err(ScenarioError::NotFound {
                name: name_or_path.to_string(),
            }),
        }
    }
}
