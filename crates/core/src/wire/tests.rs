use core::time::Duration;

use crate::time::Time;

/// Step `k`'s time at 100 Hz.
fn at(k: u64) -> Time {
    Time::at_step(k, 0.01)
}

/// A consensus round's message carrying a 2-state information pair (node 2 to node 9, step 9).
pub(crate) fn information_round() -> super::Datagram {
    use super::*;
    Datagram {
        header: Header::round(2, 9, 0, 4, at(9), at(9) + Duration::from_millis(3)),
        payload: Payload::Round {
            round: 1,
            body: Body::Information {
                n: 2,
                sym: vec![1.0, 0.5, 2.0],
                vec: vec![0.25, -1.0],
            },
        },
    }
}

/// The fuzz target's seed corpus (`fuzz/seeds/datagram/`): datagrams of every kind, a sealed one and frames
/// holding them, in the current format (`SIMNET_BLESS=1 cargo test fuzz_seeds` rewrites them after a change).
#[test]
fn fuzz_seeds_are_current_datagrams() {
    use super::secure::{Key, Sealer};
    let measurement = Datagram {
        header: Header::new(3, 9, 17, at(12345)),
        payload: Payload::measurement(0b101101, vec![0.1, -0.2, 9.8, 0.25]),
    };
    let datagrams = [
        measurement.clone(),
        Datagram {
            header: Header::hello(1, 4, 2, at(3)),
            payload: Payload::Hello {
                running: Some(40),
                run: 7,
                boot: 9,
                echo: 11,
                probe: 13,
                answer: 0,
            },
        },
        information_round(),
        Datagram {
            header: Header::round(2, BROADCAST, 6, 6, at(9), at(9)),
            payload: Payload::Round {
                round: 0,
                body: Body::Estimate {
                    n: 2,
                    x: vec![1.0, 2.0],
                    sym: vec![1.0, 0.0, 1.0],
                },
            },
        },
        Datagram {
            header: Header::round(2, BROADCAST, 7, 9, at(10), at(10)),
            payload: Payload::Round {
                round: 1,
                body: Body::Own(vec![0, 0, 128, 63, 0, 0, 0, 64]),
            },
        },
    ];
    let mut seeds: Vec<(String, Vec<u8>)> = datagrams
        .iter()
        .enumerate()
        .map(|(i, d)| (format!("datagram-{i}"), d.encode().unwrap().to_vec()))
        .collect();
    // Sealed under the fuzz target's key, for its node 9 in boot 5.
    let sealed = Sealer::new(&Key::from_bytes([7; 16]), 3, 1)
        .seal(&measurement, 9, 5)
        .unwrap();
    seeds.push(("sealed-0".into(), sealed.to_vec()));
    let bytes: Vec<Bytes> = datagrams.iter().map(|d| d.encode().unwrap()).collect();
    seeds.push(("frame-0".into(), Frame::pack(4, bytes)[0].to_vec()));
    seeds.push(("empty-frame-0".into(), Frame::pack(5, Vec::new())[0].to_vec()));
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/datagram");
    if std::env::var_os("SIMNET_BLESS").is_some() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            std::fs::remove_file(e.path()).unwrap();
        }
        for (name, b) in &seeds {
            std::fs::write(dir.join(name), b).unwrap();
        }
    }
    for (name, b) in &seeds {
        let committed = std::fs::read(dir.join(name)).unwrap_or_default();
        assert_eq!(
            &committed, b,
            "fuzz/seeds/datagram/{name} is stale: SIMNET_BLESS=1 cargo test fuzz_seeds"
        );
    }
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        seeds.len(),
        "a seed not made here"
    );
}

use super::*;

fn sample() -> Datagram {
    Datagram {
        header: Header::new(2, 7, 99, at(1234)),
        payload: Payload::measurement(0b111000, vec![0.1, -0.2, 3.0]),
    }
}

#[test]
fn every_single_bit_flip_is_caught() {
    for d in [sample(), information_round()] {
        let bytes = d.encode().unwrap();
        for bit in 0..bytes.len() * 8 {
            let mut b = bytes.to_vec();
            b[bit / 8] ^= 1 << (bit % 8);
            assert!(Datagram::decode(&b).is_err(), "{d:?}: bit {bit} went undetected");
        }
    }
}

#[test]
fn bad_lengths_and_impossible_values() {
    assert_eq!(Datagram::decode(&[]), Err(WireError::TooShort(0)));
    assert!(matches!(Datagram::decode(&[0u8; 1500]), Err(WireError::TooLong(1500))));
    let mut d = sample();
    d.payload = Payload::measurement(0b1, vec![f64::NAN]);
    assert!(d.encode().is_err());
    d.payload = Payload::measurement(0b11, vec![1.0]);
    assert!(d.encode().is_err());
    let mut d = sample();
    d.header.flags = 1;
    assert_eq!(d.encode(), Err(WireError::Flags(1)));
    // A valid body with a valid CRC but a wrong magic.
    let mut body = postcard::to_allocvec(&(
        Header {
            magic: 1,
            ..sample().header
        },
        &sample().payload,
    ))
    .unwrap();
    let crc = crc32fast::hash(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(Datagram::decode(&body), Err(WireError::Magic(1)));
}

#[test]
fn hello_round_trips_and_kind_must_match() {
    let h = Datagram {
        header: Header::hello(4, 2, 1, at(80)),
        payload: Payload::Hello {
            running: Some(77),
            run: 5,
            boot: 6,
            echo: 0,
            probe: 0,
            answer: 3,
        },
    };
    assert_eq!(Datagram::decode(&h.encode().unwrap()).unwrap(), h);
    let bad = Datagram {
        header: Header::new(4, 2, 1, Time::ZERO),
        payload: Payload::Hello {
            running: None,
            run: 5,
            boot: 6,
            echo: 0,
            probe: 0,
            answer: 3,
        },
    };
    assert!(bad.encode().is_err());
}

/// A scheme byte outside a round's message, or a time sent before the time it pertains to, is refused; a
/// broadcast is for everyone, a unicast for its receiver only.
#[test]
fn header_fields_are_checked() {
    let mut d = sample();
    d.header.scheme = 3;
    assert_eq!(
        d.encode(),
        Err(WireError::Invalid("a scheme named outside a round's message"))
    );
    let mut d = sample();
    d.header.sent = at(1233);
    assert_eq!(
        d.encode(),
        Err(WireError::Invalid("sent before the time it pertains to"))
    );
    let h = sample().header;
    assert!(h.is_for(7) && !h.is_for(2) && !h.is_for(8));
    let b = Header { dst: BROADCAST, ..h };
    assert!(b.is_for(7) && b.is_for(8));
    // A broadcast and a small id take one byte each, and read back as themselves.
    let broadcast = Datagram {
        header: b,
        payload: sample().payload,
    };
    let bytes = broadcast.encode().unwrap();
    assert_eq!(bytes.len(), sample().encode().unwrap().len());
    assert_eq!(Datagram::decode(&bytes).unwrap().header.dst, BROADCAST);
    for dst in [0, 126, 127, u32::MAX - 1] {
        let d = Datagram {
            header: Header { dst, ..h },
            payload: sample().payload,
        };
        assert_eq!(Datagram::decode(&d.encode().unwrap()).unwrap(), d, "{dst}");
    }
    // Times survive the wire to the nanosecond, up to the largest.
    let mut d = information_round();
    d.header.pertains = Time::from_nanos(u64::MAX - 1);
    d.header.sent = Time::from_nanos(u64::MAX);
    assert_eq!(Datagram::decode(&d.encode().unwrap()).unwrap(), d);
}

#[test]
fn round_messages_round_trip_and_are_checked() {
    let n = 9;
    let tri = |v: f64| vec![v; n * (n + 1) / 2];
    let d = Datagram {
        header: Header::round(1, 2, 5, 5, at(77), at(77)),
        payload: Payload::Round {
            round: 2,
            body: Body::Hybrid {
                n: n as u8,
                prior: (tri(0.5), vec![1.0; n]),
                measurement: (tri(-0.25), vec![2.0; n]),
            },
        },
    };
    let bytes = d.encode().unwrap();
    // A 9-state hybrid message (the pose model's HCMCI) fits one datagram.
    assert_eq!(bytes.len(), 896);
    assert_eq!(Datagram::decode(&bytes).unwrap(), d);
    for bad in [
        Body::Estimate {
            n: 3,
            x: vec![0.0; 3],
            sym: vec![0.0; 5],
        },
        Body::Estimate {
            n: 0,
            x: vec![],
            sym: vec![],
        },
        Body::Information {
            n: 2,
            sym: vec![1.0, f64::INFINITY, 1.0],
            vec: vec![0.0; 2],
        },
        Body::Measurement {
            rows: 0b11,
            values: vec![1.0],
        },
        Body::Own(Vec::new()),
    ] {
        let d = Datagram {
            header: Header::round(1, 2, 5, 3, at(77), at(77)),
            payload: Payload::Round { round: 0, body: bad },
        };
        assert!(matches!(d.encode(), Err(WireError::Invalid(_))), "{d:?}");
    }
}

/// A scheme's own bytes travel as they are: its encoding is the header, the round, the bytes' length as a varint
/// and the bytes, then the checksum; too many for a datagram are refused.
#[test]
fn a_schemes_own_bytes_travel_as_they_are() {
    let header = Header::round(1, 2, 5, 9, at(77), at(77));
    let clear = Datagram {
        header,
        payload: Payload::Hello {
            running: None,
            run: 0,
            boot: 0,
            echo: 0,
            probe: 0,
            answer: 0,
        },
    };
    // The header's length, from a payload of known length: Hello with six zero fields is 1 (variant) + 6 bytes.
    let head = postcard::to_allocvec(&clear.header).unwrap().len();
    for n in [1usize, 127, 128, 1000] {
        let body: Vec<u8> = (0..n).map(|i| (i * 7 % 251) as u8).collect();
        let d = Datagram {
            header,
            payload: Payload::Round {
                round: 1,
                body: Body::Own(body.clone()),
            },
        };
        let varint = if n < 128 { 1 } else { 2 };
        // payload variant, round, body variant, length, bytes; then the CRC.
        let want = head + 1 + 1 + 1 + varint + n + CRC_LEN;
        match d.encode() {
            Ok(bytes) => {
                assert_eq!(bytes.len(), want, "{n} bytes");
                assert_eq!(Datagram::decode(&bytes).unwrap(), d);
                assert_eq!(Datagram::encoded_len(&d.header, &d.payload).unwrap(), want);
            }
            Err(e) => {
                assert!(want > MAX_DATAGRAM, "{n} bytes refused: {e}");
                assert_eq!(e, WireError::TooLong(want));
            }
        }
    }
}

#[test]
fn oversized_measurement_is_refused() {
    let d = Datagram {
        header: Header::new(0, 1, 0, Time::ZERO),
        payload: Payload::measurement(u64::MAX, vec![1.0; 64]),
    };
    assert!(d.encode().is_ok());
    let big = Datagram {
        header: Header::new(0, 1, 0, Time::ZERO),
        payload: Payload::Measurement {
            rows: u64::MAX,
            values: vec![1.0; 200],
        },
    };
    assert!(big.encode().is_err());
}

#[test]
fn encoded_len_is_the_encoding_length() {
    let mut ds = vec![sample(), information_round()];
    ds.push(Datagram {
        header: Header::hello(3, BROADCAST, u32::MAX, Time::from_nanos(u64::MAX)),
        payload: Payload::Hello {
            running: Some(12),
            run: 7,
            boot: u64::MAX,
            echo: 0,
            probe: u64::MAX,
            answer: 1,
        },
    });
    ds.push(Datagram {
        header: Header::new(0, BROADCAST - 1, u32::MAX, Time::ZERO),
        payload: Payload::measurement(u64::MAX, vec![1.0; 64]),
    });
    for d in ds {
        assert_eq!(
            Datagram::encoded_len(&d.header, &d.payload).unwrap(),
            d.encode().unwrap().len(),
            "{d:?}"
        );
    }
    // Counted even past the limit that encoding refuses.
    let big = Payload::Measurement {
        rows: u64::MAX,
        values: vec![1.0; 200],
    };
    assert!(Datagram::encoded_len(&Header::new(0, 1, 0, Time::ZERO), &big).unwrap() > MAX_DATAGRAM);
}
