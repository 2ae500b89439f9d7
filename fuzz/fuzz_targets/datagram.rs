//! Untrusted bytes off the network: a datagram, a sealed datagram, and a virtual-clock frame with the datagrams
//! inside it. Decoding and opening return a value or an error; they never panic; what decodes encodes to bytes that
//! decode to it again, and seals to bytes that open to it exactly once.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::wire::secure::{Key, Opener, Sealer};
use simnet::wire::{Datagram, FrameView, Nack};

fuzz_target!(|data: &[u8]| {
    let key = Key::from_bytes([7; 16]);
    // Forged bytes: the tag cannot verify, whatever else they claim.
    // Node 9 in boot 5 (the seeds are sealed for it).
    let mut opener = Opener::new(&key, 9, 5);
    let _ = opener.open(data, |src| src < 4);
    if let Ok(d) = Datagram::decode(data) {
        let again = d.encode().expect("a decoded datagram encodes");
        assert_eq!(
            Datagram::decode(&again).as_ref(),
            Ok(&d),
            "encode then decode changed the datagram"
        );
        let mut sealer = Sealer::new(&key, d.header.src, 1);
        let mut d = d;
        // Addressed to node 9, whatever it was addressed to: a sealer seals only for the node a header names.
        d.header.dst = 9;
        if let Ok(sealed) = sealer.seal(&d, 9, 5) {
            assert!(
                Opener::new(&key, 8, 5).open(&sealed, |_| true).is_err(),
                "a datagram opened at a node it was not sealed for"
            );
            let mut opener = Opener::new(&key, 9, 5);
            let (opened, epoch, counter) = opener.open(&sealed, |_| true).expect("a sealed datagram opens");
            assert_eq!((opened.payload, epoch, counter), (d.payload.clone(), 1, 0));
            assert!(opener.open(&sealed, |_| true).is_err(), "a replay opened");
        }
    }
    if let Ok(f) = FrameView::parse(data) {
        for inner in f.datagrams() {
            let _ = Datagram::decode(inner);
        }
    }
    if let Some(n) = Nack::parse(data) {
        assert_eq!(Nack::parse(&n.encode()), Some(n), "a NACK round-trips");
    }
});
