//! What must never repeat from one run or process to the next, drawn from the operating system's random source:
//! boot epochs (sealing keys derive from them) and the random part of the names simnet writes under.

/// `n` random bytes; the time mixed in where the system has no random source (a later call does not repeat it).
fn bytes<const N: usize>() -> [u8; N] {
    let mut b = [0u8; N];
    if getrandom::getrandom(&mut b).is_err() {
        let t = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        for (i, x) in b.iter_mut().enumerate() {
            *x = (t >> (8 * (i % 16))) as u8 ^ (std::process::id() >> (8 * (i % 4))) as u8;
        }
    }
    b
}

/// A boot's epoch: milliseconds since 1970 in the high bits, 16 random bits below — larger than any earlier boot's
/// as long as the clock does not step back, and two boots in one millisecond still differ. Every boot seals under
/// keys derived from it (`wire::secure`): one rule for a node process and for every run in one process.
pub fn boot_epoch() -> u64 {
    let ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    (ms << 16) | u64::from(u16::from_le_bytes(bytes::<2>()))
}

/// 16 random hex digits: the part of a temporary or per-process file name that no other writer picks.
pub fn token() -> String {
    token_bytes().iter().map(|x| format!("{x:02x}")).collect()
}

/// A fresh sealing key from the operating system's random source (`simnet keygen`, a node without `--key`).
pub fn key() -> Result<crate::wire::secure::Key, getrandom::Error> {
    let mut k = [0u8; 16];
    getrandom::getrandom(&mut k)?;
    Ok(crate::wire::secure::Key::from_bytes(k))
}

/// 8 random bytes (a challenge no one can guess).
pub fn token_bytes() -> [u8; 8] {
    bytes::<8>()
}

#[cfg(test)]
mod tests {
    #[test]
    fn epochs_grow_and_tokens_differ() {
        let (a, b) = (super::boot_epoch(), super::boot_epoch());
        assert!(b >> 16 >= a >> 16, "{a} then {b}");
        let t: std::collections::HashSet<String> = (0..100).map(|_| super::token()).collect();
        assert_eq!(t.len(), 100);
        assert!(t
            .iter()
            .all(|x| x.len() == 16 && x.bytes().all(|c| c.is_ascii_hexdigit())));
    }
}
