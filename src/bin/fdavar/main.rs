//! `fdavar`: the offline command-line tool. Parses arguments, calls the library, maps outcomes to exit codes.
fn main() {
    eprintln!("fdavar: not built yet");
    std::process::exit(1);
}
