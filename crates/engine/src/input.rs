//! Reading files simnet did not write itself — topologies, recorded IMU files, the parts of a multi-host run, a
//! campaign's records: regular files only (a fifo would block, a device never end), no more bytes than the kind of
//! file can need, text in UTF-8. Errors say what is wrong with the file, never what is in it.

use std::io::{self, BufRead, Read};
use std::path::Path;

/// A topology file.
pub const MAX_TOPOLOGY: u64 = 16 << 20;
/// A key file.
pub const MAX_KEY: u64 = 4 << 10;
/// A JSON document simnet wrote (a part's summary, a campaign's record).
pub const MAX_JSON: u64 = 64 << 20;
/// A table: a recorded IMU file, a part's trace or estimates.
pub const MAX_TABLE: u64 = 1 << 30;

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// `path` opened for reading, if it is a regular file of at most `limit` bytes.
fn open(path: &Path, limit: u64) -> io::Result<std::fs::File> {
    // The file's own metadata, links followed: a link to /dev/zero is a device.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            use std::os::unix::fs::FileTypeExt;
            let t = meta.file_type();
            if t.is_fifo() {
                "a fifo"
            } else if t.is_char_device() || t.is_block_device() {
                "a device"
            } else if t.is_socket() {
                "a socket"
            } else {
                "not a regular file"
            }
        };
        return Err(invalid(format!("not a regular file ({what})")));
    }
    if meta.len() > limit {
        return Err(invalid(format!(
            "{} bytes, more than the {} such a file may have",
            meta.len(),
            size_text(limit)
        )));
    }
    std::fs::File::open(path)
}

pub use simnet_core::text::{clip, quoted};

/// `limit` as a reader would say it: bytes below a MiB.
fn size_text(limit: u64) -> String {
    if limit < 1 << 20 {
        format!("{limit} bytes")
    } else {
        format!("{} MiB", limit >> 20)
    }
}

/// A network key file: a regular file of at most [`MAX_KEY`] bytes that its owner can read and no one else can (as
/// ssh asks of a private key), holding one key line. The message names the file and says how to mend it.
pub fn read_key(path: &Path) -> Result<crate::wire::secure::Key, String> {
    let shown = path.display();
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read {shown}: {e}"))?;
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = meta.permissions().mode() & 0o777;
        if meta.is_file() && mode & 0o077 != 0 {
            return Err(format!(
                "{shown}: a network key must be readable by its owner alone, this one has mode {mode:04o}: \
                 chmod 600 {shown}"
            ));
        }
        if meta.is_file() && mode & 0o400 == 0 {
            return Err(format!(
                "{shown}: its owner cannot read it (mode {mode:04o}): chmod 600 {shown}"
            ));
        }
    }
    let text = read_text(path, MAX_KEY).map_err(|e| format!("cannot read {shown}: {e}"))?;
    crate::wire::secure::Key::parse(&text).map_err(|e| format!("{shown}: {e}"))
}

/// The whole text of `path` (see the module's rules).
pub fn read_text(path: &Path, limit: u64) -> io::Result<String> {
    let mut bytes = Vec::new();
    // The size was checked, but a file may grow while it is read.
    open(path, limit)?.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(invalid(format!(
            "more than the {} such a file may have",
            size_text(limit)
        )));
    }
    let mut text = String::from_utf8(bytes)
        .map_err(|e| invalid(format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))?;
    // A byte-order mark (spreadsheets write one) is no part of the first column's name.
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// `path` as lines to stream (see the module's rules); reading stops at `limit` bytes.
pub fn open_lines(path: &Path, limit: u64) -> io::Result<impl BufRead> {
    Ok(io::BufReader::new(open(path, limit)?.take(limit)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_order_mark_is_not_read_as_text() {
        let p = std::env::temp_dir().join(format!("simnet-bom-{}.csv", std::process::id()));
        std::fs::write(&p, "\u{feff}t,ax\n0,1\n").unwrap();
        assert_eq!(read_text(&p, 1024).unwrap(), "t,ax\n0,1\n");
        let _ = std::fs::remove_file(&p);
    }

    #[test]
    fn quotes_are_short() {
        assert_eq!(quoted("1.5x"), "`1.5x`");
        let long = "9".repeat(63_000_000 / 1000);
        let q = quoted(&long);
        assert!(q.len() < 80 && q.ends_with("(63000 bytes)"), "{q}");
        assert_eq!(size_text(4096), "4096 bytes");
        assert_eq!(size_text(64 << 20), "64 MiB");
    }

    #[test]
    fn only_bounded_regular_text_files_are_read() {
        let d = std::env::temp_dir().join(format!("simnet-input-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("a.toml");
        std::fs::write(&f, "x = 1\n").unwrap();
        assert_eq!(read_text(&f, 100).unwrap(), "x = 1\n");
        let e = read_text(&f, 3).unwrap_err().to_string();
        assert!(e.contains("more than"), "{e}");
        for (path, says) in [(Path::new("/dev/zero"), "a device"), (d.as_path(), "a directory")] {
            let e = read_text(path, MAX_TOPOLOGY).unwrap_err().to_string();
            assert!(e.contains(says), "{}: {e}", path.display());
        }
        let bin = d.join("b.bin");
        std::fs::write(&bin, [b'o', b'k', 0xff, 0xfe]).unwrap();
        let e = read_text(&bin, 100).unwrap_err().to_string();
        assert!(e.contains("not UTF-8") && !e.contains("ok"), "{e}");
        let _ = std::fs::remove_dir_all(d);
    }
}
