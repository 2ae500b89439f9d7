fn main() -> std::process::ExitCode {
    simnet::cli::main()
}
