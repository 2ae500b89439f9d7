//! Untrusted text as an error message shows it: clipped, never a whole file.

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
