//! Multi-host runs: `simnet node` (one node of a scenario per process), `simnet collect` (merging their parts),
//! `simnet compose` (the docker compose file).

use super::*;

#[derive(Args, Debug, Clone)]
#[command(mut_arg("out", |a| a.help("Write this node's part here: node-ID.json, trace-ID.csv, estimates-ID.csv (for `simnet collect`)").long_help(None)))]
// A node always runs on the wall clock and refuses a key derived from the seed: neither option is offered.
#[command(mut_arg("realtime", |a| a.hide(true)), mut_arg("auth", |a| a.hide(true)))]
pub struct NodeArgs {
    /// This node's id in the topology.
    #[arg(long)]
    pub id: u32,
    /// Address to bind (default: the node's `addr` in the topology, or `node<ID>:7000`, resolved; 0.0.0.0:PORT only
    /// when given).
    #[arg(long)]
    pub bind: Option<std::net::SocketAddr>,
    /// A neighbour's address, overriding the topology (`addr`, default `node<ID>:7000`). Repeatable.
    #[arg(allow_hyphen_values = true, long = "peer", value_name = "ID=HOST:PORT", value_parser = peer)]
    pub peers: Vec<(u32, String)>,
    /// Seconds to wait for every neighbour before starting alone.
    #[arg(allow_hyphen_values = true, long, default_value_t = 30.0, value_parser = seconds_in_a_day)]
    pub handshake_timeout: f64,
    /// Run without authenticating datagrams (anyone who can reach the port can then feed this node).
    #[arg(long)]
    pub insecure: bool,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Args, Debug, Clone)]
pub struct CollectArgs {
    /// Directories holding node-*.json parts.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where to write the merged summary.json, trace.csv, links.csv and plots (default: the first directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the merged summary.json instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug, Clone)]
pub struct ComposeArgs {
    /// Built-in name or path of the topology to run, one container per node.
    #[arg(long, short = 't')]
    pub topology: String,
    /// Image name of the simnet image.
    #[arg(long, default_value = "simnet:latest")]
    pub image: String,
    /// The network key handed to the containers as a Docker secret; written (`simnet keygen`) when absent.
    #[arg(long, default_value = "simnet.key", conflicts_with = "insecure")]
    pub key_file: PathBuf,
    /// Nodes that do not authenticate their datagrams (no key, no secret).
    #[arg(long)]
    pub insecure: bool,
}

#[derive(Args, Debug, Clone)]
pub struct KeygenArgs {
    /// Where to write the key (readable by its owner alone); `-` prints it.
    #[arg(default_value = "simnet.key")]
    pub file: PathBuf,
    /// Replace an existing file.
    #[arg(long)]
    pub force: bool,
}

/// Write a fresh key to `path`, readable by its owner alone; an existing file is kept unless `force`.
fn write_key(path: &std::path::Path, force: bool) -> anyhow::Result<()> {
    use std::io::Write;
    let key = crate::fresh::key().map_err(|e| anyhow::anyhow!("no random source: {e}"))?;
    if !force && std::fs::symlink_metadata(path).is_ok() {
        return Err(UsageError::Option(format!(
            "{} exists: keep it, or replace it with --force (nodes holding the old key then reject the new one's datagrams)",
            path.display()
        ))
        .into());
    }
    // Always a new file of mode 0600 (a random name, never through a link), renamed over the path: `--force` neither
    // keeps an old file's mode nor writes through a link planted under the name.
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", crate::fresh::token()));
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create_new(true);
    std::os::unix::fs::OpenOptionsExt::mode(&mut o, 0o600);
    let mut f = o
        .open(&tmp)
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
    let written = f.write_all(key.to_file().as_bytes()).and_then(|_| f.sync_all());
    let placed = written.and_then(|_| {
        if force {
            std::fs::rename(&tmp, path)
        } else {
            // No --force: a file that appeared meanwhile is kept (link fails where the name exists).
            std::fs::hard_link(&tmp, path).and_then(|_| std::fs::remove_file(&tmp))
        }
    });
    if let Err(e) = placed {
        let _ = std::fs::remove_file(&tmp);
        return Err(match e.kind() {
            std::io::ErrorKind::AlreadyExists => UsageError::Option(format!(
                "{} exists: keep it, or replace it with --force",
                path.display()
            ))
            .into(),
            _ => anyhow::anyhow!("cannot write {}: {e}", path.display()),
        });
    }
    Ok(())
}

pub(super) fn keygen(args: &KeygenArgs) -> anyhow::Result<ExitCode> {
    if args.file.as_os_str() == "-" {
        let key = crate::fresh::key().map_err(|e| anyhow::anyhow!("no random source: {e}"))?;
        out!("{}", key.to_file());
    } else {
        write_key(&args.file, args.force)?;
        eprintln!(
            "wrote {}: give it to every node (--key-file, SIMNET_KEY_FILE or [security] key_file)",
            args.file.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn peer(s: &str) -> Result<(u32, String), String> {
    let (id, addr) = s
        .split_once('=')
        .ok_or_else(|| format!("expected ID=HOST:PORT, got `{s}`"))?;
    let id = id.parse::<u32>().map_err(|_| format!("`{id}` is not a node id"))?;
    crate::scenario::check_addr(addr)?;
    Ok((id, addr.to_string()))
}

pub(super) fn run_node(args: &NodeArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    use crate::net::host::{run_node, HostConfig};
    let topo = Arc::new(args.run.topology()?);
    if let Some(k) = topo.estimators().run.iter().find(|k| k.is_center()) {
        return Err(UsageError::Option(format!(
            "--estimators {}: a fusion center needs every node's measurement in one process (simnet run); \
             one node per process runs the schemes the nodes run themselves",
            k.name()
        ))
        .into());
    }
    let index = topo.index_of(args.id).ok_or_else(|| {
        UsageError::Option(format!(
            "--id {}: no [[node]] has this id in `{}`",
            args.id,
            topo.name()
        ))
    })?;
    let peers =
        crate::net::host::neighbour_addrs(&topo, index, &args.peers).map_err(|e| UsageError::Option(e.to_string()))?;
    // An address given on the command line resolves now (a topology's names may come up later, in containers).
    for (id, addr) in &args.peers {
        use std::net::ToSocketAddrs;
        if let Err(e) = addr.to_socket_addrs() {
            return Err(UsageError::Option(format!("--peer {id}={addr}: cannot resolve it: {e}")).into());
        }
    }
    let own = crate::compose::node_addr(&topo, index);
    own.rsplit_once(':')
        .and_then(|(_, p)| p.parse::<u16>().ok())
        .ok_or_else(|| UsageError::Option(format!("node {}: address `{own}` has no port", args.id)))?;
    match (&topo.security().key_source, args.insecure) {
        (None, false) => {
            return Err(UsageError::Option(
                "simnet node authenticates every datagram: give the network's key with --key-file FILE \
                 (`simnet keygen`), SIMNET_KEY_FILE or [security] key_file — or --insecure to run without"
                    .into(),
            )
            .into())
        }
        (Some(s), _) if s == "seed" => {
            return Err(UsageError::Option(
                "[security] auth = true derives a key from the run seed, which anyone knows: give a key file".into(),
            )
            .into())
        }
        (Some(_), true) => {
            return Err(UsageError::Option("--insecure and a key: choose one".into()).into());
        }
        _ => {}
    }
    if args.run.format != Format::Csv {
        return Err(UsageError::Option(
            "a node writes its part as CSV; `simnet collect` merges the parts: drop --format".into(),
        )
        .into());
    }
    // The output directory before the address: every bad option is named before the node waits for anything.
    let out_dir = args.run.out.as_deref().map(PartDir::prepare).transpose()?;
    // The node's own address from the topology (its service name in a container), never every interface unless
    // --bind asks for it.
    let bind = match args.bind {
        Some(b) => b,
        None => {
            use std::net::ToSocketAddrs;
            let resolved = own.to_socket_addrs().ok().and_then(|mut a| a.find(|a| a.is_ipv4()));
            resolved.ok_or_else(|| {
                UsageError::Option(format!(
                    "node {}: cannot resolve its own address `{own}` to bind it; give --bind ADDR",
                    args.id
                ))
            })?
        }
    };
    let steps = topo.sim().steps();
    let progress = (!quiet && !args.run.json).then(|| progress_bar(steps));
    let cfg = HostConfig {
        bind,
        peers,
        handshake_timeout: std::time::Duration::from_secs_f64(args.handshake_timeout),
        record_trace: args.run.out.is_some(),
        progress: progress
            .clone()
            .map(|pb| -> net::Progress { Arc::new(move |d, _| pb.set_position(d)) }),
        boot_epoch: crate::fresh::boot_epoch(),
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let out = rt.block_on(run_node(topo.clone(), index, cfg, shutdown_signal()))?;
    if let Some(pb) = progress {
        pb.finish_and_clear();
    }
    let s = out.part(&topo, index);
    if let Some(d) = &out_dir {
        let mut buf = Vec::new();
        crate::report::trace::write_trace(&mut buf, &topo.model().get().columns(), &out.report.trace)?;
        d.put(&format!("trace-{}.csv", args.id), &buf)?;
        let mut buf = Vec::new();
        crate::report::parts::write_estimates(&mut buf, &out.estimates)?;
        d.put(&format!("estimates-{}.csv", args.id), &buf)?;
        // The part last: its presence means the node finished writing.
        d.put(&format!("node-{}.json", args.id), s.to_json().as_bytes())?;
    }
    print_summary(
        &s,
        args.run.json,
        Some("(per-link figures: `simnet collect` on the parts of every node)"),
    )?;
    if let Some(refused) = crate::report::parts::unheard(&s).filter(|_| !out.heard_a_hello) {
        // Not even a hello opened (an earlier run's replayed hellos would): the keys differ. The part is written.
        eprintln!(
            "error: no datagram from a neighbour authenticated ({refused} refused with a bad tag): do the nodes share a \
             key? (`simnet keygen` once, the same file to every node)"
        );
        return Ok(ExitCode::from(2));
    }
    Ok(exit_code(s.interrupted))
}

pub(super) fn collect(args: &CollectArgs) -> anyhow::Result<ExitCode> {
    use crate::report::parts::{merge, read_parts, Parts};
    let Parts {
        summaries: parts,
        estimates,
        mut rows,
        columns,
    } = read_parts(&args.dirs).map_err(|e| UsageError::Option(e.to_string()))?;
    let (s, mut observer) = merge(&parts, &estimates).map_err(|e| UsageError::Option(e.to_string()))?;
    let d = RunDir::open(args.out.as_deref().unwrap_or(&args.dirs[0]), &[])?;
    rows.sort_by_key(|r| (r.step, r.node, r.filter));
    let dt = 1.0 / s.rate_hz;
    let mut rec = TraceWriter::new(columns, observer.layout(), dt, s.steps).to_writer(d.create("trace.csv")?);
    // Fused rows go after the node rows of their step.
    let mut fused = observer.drain_rows().into_iter().peekable();
    for chunk in rows.chunk_by(|a, b| a.step == b.step) {
        rec.rows(chunk.to_vec());
        let step = chunk[0].step;
        let mut now = Vec::new();
        while let Some(f) = fused.next_if(|f| f.step <= step) {
            now.push(f);
        }
        rec.fused(now);
    }
    rec.fused(fused.collect());
    let (rows, fused) = d.finish_trace(Some(rec))?;
    let wrote = write_files(&d.stage, &s, dt, &rows, &fused, Vec::new())?;
    let dir = d.dir.clone();
    d.commit(&wrote)?;
    print_summary(&s, args.json, None)?;
    if !args.json {
        outln!("\nwrote {}/{{{}}}", dir.display(), wrote.join(", "));
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn compose(args: &ComposeArgs) -> anyhow::Result<ExitCode> {
    let topo = Scenario::resolve(&args.topology).map_err(UsageError::from)?;
    for w in topo.warnings() {
        eprintln!("warning: {}: {w}", topo.name());
    }
    let builtin = builtin::get(&args.topology).is_some();
    let secret = if args.insecure {
        None
    } else {
        let path = &args.key_file;
        if path.exists() {
            crate::input::read_key(path).map_err(UsageError::Option)?;
        } else {
            write_key(path, false)?;
            eprintln!(
                "wrote a new network key to {} (the compose file hands it to the nodes as a Docker secret)",
                path.display()
            );
        }
        Some(path.display().to_string())
    };
    out!(
        "{}",
        crate::compose::compose_file(&topo, &args.topology, builtin, &args.image, secret.as_deref())
            .map_err(UsageError::Option)?
    );
    Ok(ExitCode::SUCCESS)
}
