//! Bad input from outside — values the command line accepts as numbers, files that are not what they should be,
//! the parts of a multi-host run crafted or mixed — exits 2 with a message that names what is wrong and quotes
//! nothing of a file that is not what it should be; never a panic, a hang or a run that quietly goes wrong.

use std::path::{Path, PathBuf};
use std::process::Command;

fn simnet() -> Command {
    Command::new(env!("CARGO_BIN_EXE_simnet"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("simnet-untrusted-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The parts of a two-node run of a scalar linear model (`simnet node` on loopback, 0.2 s), in `dir/a` (node 0) and
/// `dir/b` (node 1).
fn two_parts(dir: &Path) -> (PathBuf, PathBuf) {
    let topo = dir.join("pair.toml");
    let ports: Vec<u16> = (0..2)
        .map(|_| {
            std::net::UdpSocket::bind("127.0.0.1:0")
                .unwrap()
                .local_addr()
                .unwrap()
                .port()
        })
        .collect();
    std::fs::write(
        &topo,
        format!(
            "[sim]\nduration_s = 0.2\nburn_in_s = 0.05\n[model]\nkind = \"linear\"\na = [[1.0]]\nc = [[1.0]]\n\
             q = [[1.0]]\nr = [[1.0]]\n[[node]]\nid = 0\naddr = \"127.0.0.1:{}\"\n[[node]]\nid = 1\n\
             addr = \"127.0.0.1:{}\"\n[[edge]]\nnodes = [0, 1]\n",
            ports[0], ports[1]
        ),
    )
    .unwrap();
    let dirs = [dir.join("a"), dir.join("b")];
    let children: Vec<_> = (0..2)
        .map(|i| {
            simnet()
                .args(["node", "-q", "--id", &i.to_string(), "--handshake-timeout", "20", "-t"])
                .arg(&topo)
                .arg("--out")
                .arg(&dirs[i])
                .stdout(std::process::Stdio::null())
                .spawn()
                .unwrap()
        })
        .collect();
    for mut c in children {
        assert!(c.wait().unwrap().success());
    }
    let [a, b] = dirs;
    (a, b)
}

fn rewrite_json(path: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(path, serde_json::to_string(&v).unwrap()).unwrap();
}

#[test]
fn every_bad_input_exits_2_naming_it() {
    let d = tmp("table");
    let passwd = d.join("passwd");
    std::fs::write(&passwd, "root:x:0:0:root:/root:/bin/bash\nsecret:x:1:1::/:/bin/sh\n").unwrap();
    let uses_passwd = d.join("imu.toml");
    std::fs::write(
        &uses_passwd,
        format!("[[node]]\nid = 0\nimu_csv = \"{}\"\n", passwd.display()),
    )
    .unwrap();
    let fifo = d.join("fifo.toml");
    let made_fifo = Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success());

    // The parts of a real run, then crafted copies.
    let (a, b) = two_parts(&d);
    let slow = d.join("slow");
    let zero = d.join("zero");
    let wide = d.join("wide");
    let stale = d.join("stale");
    for (copy, from) in [(&slow, &a), (&zero, &a), (&wide, &b), (&stale, &a)] {
        std::fs::create_dir_all(copy).unwrap();
        for e in std::fs::read_dir(from).unwrap().flatten() {
            std::fs::copy(e.path(), copy.join(e.file_name())).unwrap();
        }
    }
    rewrite_json(&slow.join("node-0.json"), |v| v["rate_hz"] = 0.0.into());
    std::fs::remove_file(zero.join("estimates-0.csv")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", zero.join("estimates-0.csv")).unwrap();
    // Node 1's estimates with one state more than the run's.
    let text = std::fs::read_to_string(wide.join("estimates-1.csv")).unwrap();
    let widened: String = text
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                return format!("{l}\n");
            }
            // step,frame,n=1,truth,x,P → n=2 with a 2×2 P.
            let f: Vec<&str> = l.split(',').collect();
            format!("{},{},2,{},0,{},0,{},0,0,0\n", f[0], f[1], f[3], f[4], f[5])
        })
        .collect();
    std::fs::write(wide.join("estimates-1.csv"), widened).unwrap();

    let s = |p: &Path| p.to_str().unwrap().to_string();
    let mut cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["-t".into(), "ring3".into(), "--jitter".into(), "1e308".into()],
            "overrides.jitter_ms",
        ),
        (
            vec![
                "-t".into(),
                "ring3".into(),
                "--delay".into(),
                "1e23".into(),
                "--realtime".into(),
            ],
            "overrides.delay_ms",
        ),
        (
            vec![
                "-t".into(),
                "ring3".into(),
                "--rate".into(),
                "1e-20".into(),
                "--realtime".into(),
            ],
            "not one step",
        ),
        (
            vec!["-t".into(), "ring3".into(), "--rate".into(), "1e7".into()],
            "overrides.rate_hz",
        ),
        (
            vec![
                "node".into(),
                "-t".into(),
                "ring3".into(),
                "--id".into(),
                "0".into(),
                "--handshake-timeout".into(),
                "1e300".into(),
            ],
            "--handshake-timeout",
        ),
        (
            vec!["validate".into(), "/dev/zero".into()],
            "not a regular file (a device)",
        ),
        (vec!["validate".into(), s(&d)], "not a regular file (a directory)"),
        (vec!["validate".into(), s(&uses_passwd)], "not an IMU file"),
        (vec!["-t".into(), s(&passwd)], "TOML parse error at line 1"),
        (vec!["collect".into(), s(&slow), s(&b)], "step rate of 0 Hz"),
        (vec!["collect".into(), s(&zero), s(&b)], "not a regular file (a device)"),
        (vec!["collect".into(), s(&a)], "have no part: node-1.json"),
        (vec!["collect".into(), s(&a), s(&b), s(&stale)], "node 0 has two parts"),
        (vec!["collect".into(), s(&a), s(&wide)], "node 1's estimates"),
    ];
    if made_fifo {
        cases.push((vec!["validate".into(), s(&fifo)], "not a regular file (a fifo)"));
    }
    for (args, says) in cases {
        let out = simnet().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?} does not say `{says}`:\n{err}");
        // Nothing of the password file is printed back.
        assert!(
            !err.contains("root:") && !err.contains("secret"),
            "{args:?} quotes the file:\n{err}"
        );
    }
    // The real parts still merge.
    let out = simnet()
        .args(["collect", "-q"])
        .arg(&a)
        .arg(&b)
        .arg("--out")
        .arg(d.join("merged"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let _ = std::fs::remove_dir_all(d);
}
