//! Results: `summary.json`, the stdout table, `trace.csv`, `links.csv`, plots and `report.html`. Writers take
//! `impl Write`.

pub mod capture;
pub mod html;
pub mod outputs;
#[cfg(feature = "parquet")]
pub mod parquet;
pub mod parts;
pub mod plot;
pub mod summary;
pub mod trace;

/// `bytes` to `path` through a temporary file in the same directory, renamed over it: a reader sees the old file or
/// the new one, never a part. The temporary name is unique per process and call, so that processes sharing a
/// directory (a campaign's shards) never write the same one.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    // The process id alone is not unique where several writers share a directory: every container's first process
    // is pid 1 (a campaign's shards on one volume). A random token per process is.
    static TOKEN: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    let token = TOKEN.get_or_init(crate::fresh::token);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{token}.{n}.tmp"));
    // `create_new`: a link planted under the temporary name is never followed.
    let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
    if let Err(e) = std::io::Write::write_all(&mut f, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}
