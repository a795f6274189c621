use clap::Parser;

fn main() {
    let cli = pegtwin::cli::Cli::parse();
    match pegtwin::cli::run(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}
