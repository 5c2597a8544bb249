fn main() {
    stiff::output::sink::install_signal_cleanup();
    if let Err(e) = stiff::cli::run() {
        // A consumer that stopped reading (`stiff map ... | head`) is not a failure of ours: stop quietly,
        // as ripgrep and xsv do.
        let broken_pipe = e
            .chain()
            .any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe));
        if broken_pipe {
            std::process::exit(0);
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
