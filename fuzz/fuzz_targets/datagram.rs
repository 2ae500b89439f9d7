//! Untrusted bytes off the network: a datagram, and a virtual-clock frame with the datagrams inside it. Decoding
//! returns a value or an error; it never panics, and what decodes encodes to bytes that decode to it again.
#![no_main]
use libfuzzer_sys::fuzz_target;
use simnet::wire::{Datagram, FrameView};

fuzz_target!(|data: &[u8]| {
    if let Ok(d) = Datagram::decode(data) {
        let again = d.encode().expect("a decoded datagram encodes");
        assert_eq!(
            Datagram::decode(&again).as_ref(),
            Ok(&d),
            "encode then decode changed the datagram"
        );
    }
    if let Ok(f) = FrameView::parse(data) {
        for inner in f.datagrams() {
            let _ = Datagram::decode(inner);
        }
    }
});
