fn main() -> std::process::ExitCode {
    simnet::cli_main()
}
