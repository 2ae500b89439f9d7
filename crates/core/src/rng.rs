//! Every random stream is derived from the logged run seed and a fixed label, never from the OS, so that each
//! node, link and sensor has its own stream and a run replays exactly.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The generator of every seeded stream: ChaCha8, the same on every platform.
pub type Rng = ChaCha8Rng;

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The stream for (`seed`, `label`, `a`, `b`), e.g. ("link", from, to) or ("sensor", node, 0).
pub fn stream(seed: u64, label: &str, a: u64, b: u64) -> Rng {
    let mut h = splitmix(seed);
    for byte in label.bytes() {
        h = splitmix(h ^ byte as u64);
    }
    h = splitmix(h ^ a);
    h = splitmix(h ^ b.rotate_left(32));
    ChaCha8Rng::seed_from_u64(h)
}
