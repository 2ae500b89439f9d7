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
