fn main() {
    if let Err(e) = stiff::cli::run() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
