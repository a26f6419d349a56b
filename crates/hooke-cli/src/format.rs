//! Output formats shared by the commands.

use clap::ValueEnum;
use comfy_table::{Table, presets::ASCII_MARKDOWN};

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutputFormat {
    /// A table for people.
    Table,
    /// JSON for programs.
    Json,
}

/// A table styled the one way every command prints tables (Markdown, so it pastes into docs).
pub fn table(mut table: Table) -> Table {
    table.load_style(ASCII_MARKDOWN);
    table
}

/// Bytes in binary units.
pub fn bytes(count: usize) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut value = count as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{count} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}
