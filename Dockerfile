# simnet node image: no base image, just the statically linked binary and the topologies.
# Build the binary first:
#   RUSTFLAGS='-C target-feature=+crt-static' cargo build --release --target x86_64-unknown-linux-gnu
FROM scratch
COPY target/x86_64-unknown-linux-gnu/release/simnet /simnet
COPY topologies /topologies
WORKDIR /
ENTRYPOINT ["/simnet"]
