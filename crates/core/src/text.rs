//! Text as a reader sees it: untrusted text clipped in an error message (never a whole file), and a table cell of a
//! Markdown page.

/// A piece of an untrusted file as a message shows it: its first 24 characters, `…` where it goes on (a message
/// never carries a file's megabytes).
pub fn clip(s: &str) -> String {
    match s.char_indices().nth(24) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

/// [`clip`] in backquotes, with the length of what was cut.
pub fn quoted(s: &str) -> String {
    let c = clip(s);
    if c.len() < s.len() {
        format!("`{c}` ({} bytes)", s.len())
    } else {
        format!("`{c}`")
    }
}

/// `s` as one cell of a Markdown table: `|` escaped, `<` and `>` as entities (a default of `node<ID>` is not read
/// as an HTML tag).
pub fn markdown_cell(s: &str) -> String {
    s.replace('|', "\\|").replace('<', "&lt;").replace('>', "&gt;")
}

/// A name a topology file can hold as a registered thing's name: lower-case letters, digits and `-`, starting with a
/// letter.
pub fn is_name(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_lowercase())
        && s.chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
}

/// `Debug`, `Display`, `Serialize` and `Deserialize` of a registry place by its name (`$name`, `from_name`); an
/// unknown name is an error naming it as a `$what`.
macro_rules! by_name {
    ($t:ty, $name:ident, $what:literal) => {
        impl std::fmt::Debug for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.$name())
            }
        }

        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.$name())
            }
        }

        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.$name())
            }
        }

        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<$t, D::Error> {
                let name = <String as serde::Deserialize>::deserialize(d)?;
                <$t>::from_name(&name)
                    .ok_or_else(|| serde::de::Error::custom(format!(concat!("unknown ", $what, " `{}`"), name)))
            }
        }
    };
}
pub(crate) use by_name;
