//! The `dampscope` binary: a thin shell around [`dampscope::cli`].

fn main() {
    std::process::exit(dampscope::cli::main_exit_code());
}
