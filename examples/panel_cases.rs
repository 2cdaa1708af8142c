//! Saturated colours on every built-in e-paper panel (the panels' part of the stability map,
//! also written by `halftone bench --stability`): CSV of every case, then the summary table.
//!
//! `cargo run --release --example panel_cases`

fn main() -> Result<(), halftone::Error> {
    let cases = halftone::panel_stability::panels(96)?;
    print!("{}", halftone::panel_stability::to_csv(&cases));
    println!();
    print!("{}", halftone::panel_stability::to_markdown(&cases));
    Ok(())
}
