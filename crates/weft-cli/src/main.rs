//! The `weft` command. All behaviour lives in the library half of this crate (`lib.rs`) so
//! integration tests can call it in-process as well as through the binary.

fn main() -> std::process::ExitCode {
    weft_cli::main_with_args(std::env::args_os())
}
