//! What the kernel does to a node's socket: its receive buffer, sized so that a burst of genuine datagrams is not
//! dropped, and the datagrams it dropped all the same (the buffer was full), counted apart from the link layer's
//! decisions.

use std::os::fd::AsRawFd;

/// The receive buffer asked for: room for about 20,000 measurement datagrams (the kernel may cap it at
/// `net.core.rmem_max`).
pub const RECV_BUFFER: usize = 4 << 20;

/// Ask for a receive buffer of `bytes`; the size the kernel granted (twice what it counts as payload on Linux).
pub fn size_buffers(socket: &impl std::os::fd::AsFd, bytes: usize) -> Option<usize> {
    let s = socket2::SockRef::from(socket);
    let _ = s.set_recv_buffer_size(bytes);
    s.recv_buffer_size().ok()
}

/// Datagrams the kernel dropped on `socket` because its receive buffer was full (Linux: the `drops` column of
/// /proc/net/udp for the socket's inode); none where that cannot be read.
pub fn kernel_drops(socket: &impl AsRawFd) -> Option<u64> {
    drops_table().get(&inode_of(socket)?).copied()
}

/// The socket's inode, as /proc/net/udp names it.
fn inode_of(socket: &impl AsRawFd) -> Option<String> {
    let link = std::fs::read_link(format!("/proc/self/fd/{}", socket.as_raw_fd())).ok()?;
    Some(link.to_str()?.strip_prefix("socket:[")?.strip_suffix(']')?.to_string())
}

/// Hand each node the datagrams the kernel dropped on its socket (nothing where they cannot be read). The tables
/// are read once for all of them: each read has the kernel write every socket's row, so a read per socket made the
/// end of a 1000-node run quadratic (a second of the ring of 1000's 1.8 s).
pub fn record_drops<'a, S: AsRawFd + 'a>(nodes: impl IntoIterator<Item = (&'a mut simnet_engine::node::Node, &'a S)>) {
    let drops = drops_table();
    for (node, socket) in nodes {
        if let Some(n) = inode_of(socket).and_then(|i| drops.get(&i)) {
            node.endpoint_mut().handle_kernel_drops(*n);
        }
    }
}

/// Every UDP socket's drops by inode, from one read of each table.
fn drops_table() -> std::collections::HashMap<String, u64> {
    ["/proc/self/net/udp", "/proc/self/net/udp6"]
        .iter()
        .filter_map(|t| std::fs::read_to_string(t).ok())
        .flat_map(|text| rows(&text).map(|(i, d)| (i.to_string(), d)).collect::<Vec<_>>())
        .collect()
}

/// (inode, drops) of each row of a /proc/net/udp table.
fn rows(table: &str) -> impl Iterator<Item = (&str, u64)> {
    table.lines().skip(1).filter_map(|l| {
        let f: Vec<&str> = l.split_whitespace().collect();
        // sl local rem st tx:rx tr:when retrnsmt uid timeout inode ref pointer drops
        (f.len() >= 13).then(|| Some((f[9], f[12].parse().ok()?))).flatten()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drops_are_read_from_the_sockets_row() {
        let table = "   sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode ref pointer drops\n\
            \x20 1: 0100007F:1F40 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 4242 2 0000000000000000 17\n\
            \x20 2: 0100007F:1F41 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 4243 2 0000000000000000 0\n";
        assert_eq!(rows(table).collect::<Vec<_>>(), [("4242", 17), ("4243", 0)]);
    }

    /// A socket nobody reads drops what overflows its buffer, and the count says how much: sent = queued + dropped.
    #[test]
    fn a_full_buffer_is_counted() {
        let rx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let s = socket2::SockRef::from(&rx);
        s.set_recv_buffer_size(4096).unwrap();
        let Some(before) = kernel_drops(&rx) else {
            eprintln!("SKIP: /proc/net/udp is not readable here");
            return;
        };
        assert_eq!(before, 0);
        let sent = 2000;
        for _ in 0..sent {
            tx.send_to(&[0u8; 64], rx.local_addr().unwrap()).unwrap();
        }
        rx.set_nonblocking(true).unwrap();
        let mut queued = 0;
        let mut buf = [0u8; 128];
        while rx.recv_from(&mut buf).is_ok() {
            queued += 1;
        }
        let dropped = kernel_drops(&rx).unwrap();
        assert!(dropped > 0, "a 4 KiB buffer held {queued} datagrams");
        assert_eq!(queued + dropped, sent);
        // One read of the tables for every socket says the same as a read for each.
        let table = drops_table();
        assert_eq!(table.get(&inode_of(&rx).unwrap()), Some(&dropped));
        assert_eq!(table.get(&inode_of(&tx).unwrap()), Some(&0));
    }
}
