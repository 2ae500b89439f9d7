//! The topologies of `topologies/`, compiled into the binary so that `simnet --topology ring3` works anywhere.

/// (name, TOML text), in the order `simnet topologies` lists them.
pub const ALL: &[(&str, &str)] = &[
    ("ring3", include_str!("../../../../topologies/ring3.toml")),
    ("ring3-radio", include_str!("../../../../topologies/ring3-radio.toml")),
    ("pair2-paper", include_str!("../../../../topologies/pair2-paper.toml")),
    ("tri3-paper", include_str!("../../../../topologies/tri3-paper.toml")),
    ("tri3-alt", include_str!("../../../../topologies/tri3-alt.toml")),
    ("line4", include_str!("../../../../topologies/line4.toml")),
    ("star5", include_str!("../../../../topologies/star5.toml")),
    ("grid16", include_str!("../../../../topologies/grid16.toml")),
    (
        "sinopoli-scalar",
        include_str!("../../../../topologies/sinopoli-scalar.toml"),
    ),
    ("ring100", include_str!("../../../../topologies/ring100.toml")),
    ("attitude3", include_str!("../../../../topologies/attitude3.toml")),
    ("rgg50", include_str!("../../../../topologies/rgg50.toml")),
    ("rgg50-radio", include_str!("../../../../topologies/rgg50-radio.toml")),
    ("ranges4", include_str!("../../../../topologies/ranges4.toml")),
    (
        "ring3-attacked",
        include_str!("../../../../topologies/ring3-attacked.toml"),
    ),
];

pub fn get(name: &str) -> Option<&'static str> {
    ALL.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}
