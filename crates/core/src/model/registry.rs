//! The one registry of models: the three built-in ones (`pose`, `attitude`, `linear`), then any a program adds with
//! [`register`]. A model's [`Kind`] is its place here and its name is `[model] kind` in a topology file; a registered
//! model is built from the file's `[model.params]` table, which it checks key by key like any other table.

use std::sync::{Arc, RwLock};

use super::{ErrorText, Model, TrajectoryView};
use crate::checks::Checks;

/// How a registered model is built from its `[model.params]` table: each problem goes to the [`Checks`] with its key
/// (`model.params.r`), and a model is returned anyway (validation then refuses the file with every problem listed).
pub type Builder = fn(&toml::Table, &mut Checks) -> Arc<dyn Model>;

/// A model as the registry holds it: its name, the words of its error figures, its trajectory plot and how it is
/// built.
#[derive(Clone, Copy)]
pub struct Registration {
    /// Its name in `[model] kind` and in summaries.
    pub name: &'static str,
    /// One line on what it estimates, for listings.
    pub about: &'static str,
    /// The words and unit of its error figures.
    pub error_text: ErrorText,
    /// How the trajectory plot shows its reported columns.
    pub view: TrajectoryView,
    /// How it is built from `[model.params]`; `None` for the built-in ones, which have typed `[model]` keys.
    pub build: Option<Builder>,
}

/// Why a model cannot be registered.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegisterError {
    /// The name is a registered model's.
    #[error("a model named `{name}` is registered already")]
    Taken {
        /// The name.
        name: &'static str,
        /// The model holding it.
        kind: Kind,
    },
    /// Not a name a topology file can hold.
    #[error("`{0}` is not a model name (lower-case letters, digits and `-`, starting with a letter)")]
    Name(&'static str),
    /// A registered model is built from its table: a builder is required.
    #[error("model `{0}` has no builder")]
    NoBuilder(&'static str),
    /// 256 models are registered.
    #[error("no room for model `{0}`: 256 models are registered")]
    Full(&'static str),
}

const POSE: Registration = Registration {
    name: "pose",
    about: "position, velocity and attitude driven by the node's IMU, fixed by position and attitude measurements",
    error_text: ErrorText {
        unit: " m",
        label: "mean position error, m",
        axis: "position error (m)",
        legend: "errors: mean position error, m",
    },
    view: TrajectoryView::Plane,
    build: None,
};

const ATTITUDE: Registration = Registration {
    name: "attitude",
    about: "a quaternion driven by the gyro, fixed by the accelerometer and the magnetometer",
    error_text: ErrorText {
        unit: "°",
        label: "mean attitude error, °",
        axis: "attitude error (°)",
        legend: "errors: mean attitude error, degrees",
    },
    view: TrajectoryView::Angles,
    build: None,
};

const LINEAR: Registration = Registration {
    name: "linear",
    about: "x⁺ = A x + w, y = C x + v, given by its matrices",
    error_text: ErrorText {
        unit: "",
        label: "mean state error",
        axis: "state error",
        legend: "errors: mean state error norm",
    },
    view: TrajectoryView::FirstColumn,
    build: None,
};

/// The built-in models, in registry order.
const BUILTIN: [&Registration; 3] = [&POSE, &ATTITUDE, &LINEAR];

/// The models a program registered, after the built-in ones.
static ADDED: RwLock<Vec<&'static Registration>> = RwLock::new(Vec::new());

/// Add a model of your own: `[model] kind = "<name>"` then builds it from `[model.params]` with `build`. Registered
/// once per process, before the scenarios that name it are read; every process of a multi-host run registers it.
/// The `simnet` crate's `sim` module runs one.
///
/// ```
/// use simnet_core::model::{register, Kind, Linear, Registration, RegisterError, ErrorText, TrajectoryView};
/// use nalgebra::{DMatrix, DVector};
///
/// let scalar = Registration {
///     name: "scalar",
///     about: "a scalar random walk, seen directly",
///     error_text: ErrorText { unit: "", label: "mean error", axis: "error", legend: "errors: mean error" },
///     view: TrajectoryView::FirstColumn,
///     build: Some(|table, ck| {
///         let q = ck.positive("model.params.q", table.get("q").and_then(|v| v.as_float()), 1.0);
///         let one = DMatrix::identity(1, 1);
///         std::sync::Arc::new(Linear::new(one.clone(), one.clone(), one.clone() * q, one.clone(), DVector::zeros(1), one))
///     }),
/// };
/// let kind = register(scalar)?;
/// assert_eq!(Kind::from_name("scalar"), Some(kind));
/// assert!(matches!(register(scalar), Err(RegisterError::Taken { .. })));
/// assert!(matches!(register(Registration { name: "pose", ..scalar }), Err(RegisterError::Taken { .. })));
/// assert!(matches!(register(Registration { name: "Scalar 2", ..scalar }), Err(RegisterError::Name(_))));
/// assert!(matches!(register(Registration { name: "bare", build: None, ..scalar }), Err(RegisterError::NoBuilder(_))));
/// # Ok::<(), RegisterError>(())
/// ```
pub fn register(model: Registration) -> Result<Kind, RegisterError> {
    let name = model.name;
    if !crate::text::is_name(name) {
        return Err(RegisterError::Name(name));
    }
    if model.build.is_none() {
        return Err(RegisterError::NoBuilder(name));
    }
    let mut added = ADDED.write().unwrap_or_else(|e| e.into_inner());
    if let Some(i) = BUILTIN.iter().chain(added.iter()).position(|r| r.name == name) {
        return Err(RegisterError::Taken {
            name,
            kind: Kind(i as u8),
        });
    }
    let id = u8::try_from(BUILTIN.len() + added.len()).map_err(|_| RegisterError::Full(name))?;
    added.push(Box::leak(Box::new(model)));
    Ok(Kind(id))
}

/// A registered model: its place in the registry.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Kind(u8);

#[allow(non_upper_case_globals)]
impl Kind {
    /// Position, velocity and attitude from a strapdown IMU and pose fixes.
    pub const Pose: Kind = Kind(0);
    /// Attitude from gyro, accelerometer and magnetometer.
    pub const Attitude: Kind = Kind(1);
    /// x⁺ = A x + w, z = C x + v, given by its matrices.
    pub const Linear: Kind = Kind(2);

    /// Its registration.
    pub fn registration(self) -> Registration {
        match BUILTIN.get(self.0 as usize) {
            Some(r) => **r,
            // A kind is only made by the registry, and a registration is never removed.
            None => *ADDED.read().unwrap_or_else(|e| e.into_inner())[self.0 as usize - BUILTIN.len()],
        }
    }

    /// Every registered model, in registry order: the built-in ones, then those a program added.
    pub fn all() -> Vec<Kind> {
        let added = ADDED.read().unwrap_or_else(|e| e.into_inner()).len();
        (0..BUILTIN.len() + added).map(|i| Kind(i as u8)).collect()
    }

    /// The model called `name`.
    pub fn from_name(name: &str) -> Option<Kind> {
        if let Some(i) = BUILTIN.iter().position(|r| r.name == name) {
            return Some(Kind(i as u8));
        }
        let added = ADDED.read().unwrap_or_else(|e| e.into_inner());
        let i = added.iter().position(|r| r.name == name)?;
        Some(Kind((BUILTIN.len() + i) as u8))
    }

    /// Its name in files and summaries.
    pub fn as_str(self) -> &'static str {
        self.registration().name
    }

    /// The words and units of the error figures: position error (pose), rotation angle (attitude), state error
    /// norm (linear).
    pub fn error_text(self) -> ErrorText {
        self.registration().error_text
    }

    /// How the trajectory plot shows the reported columns.
    pub fn trajectory_view(self) -> TrajectoryView {
        self.registration().view
    }

    /// Every registered model's name, for a message listing what `kind` may be.
    pub fn names() -> String {
        let names: Vec<&str> = Kind::all().into_iter().map(Kind::as_str).collect();
        names.join(" | ")
    }
}

crate::text::by_name!(Kind, as_str, "model");
