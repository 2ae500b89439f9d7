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
            "{} bytes, more than the {} MiB such a file may have",
            meta.len(),
            limit >> 20
        )));
    }
    std::fs::File::open(path)
}

/// The whole text of `path` (see the module's rules).
pub fn read_text(path: &Path, limit: u64) -> io::Result<String> {
    let mut bytes = Vec::new();
    // The size was checked, but a file may grow while it is read.
    open(path, limit)?.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(invalid(format!(
            "more than the {} MiB such a file may have",
            limit >> 20
        )));
    }
    String::from_utf8(bytes).map_err(|e| invalid(format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))
}

/// `path` as lines to stream (see the module's rules); reading stops at `limit` bytes.
pub fn open_lines(path: &Path, limit: u64) -> io::Result<impl BufRead> {
    Ok(io::BufReader::new(open(path, limit)?.take(limit)))
}

#[cfg(test)]
mod tests {
    use super::*;

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
