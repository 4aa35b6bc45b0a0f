//! Reports for people: what `penumbra compare` and `penumbra bench` leave behind besides their
//! tables — a contact sheet of every technique's image next to its error, and a static HTML page
//! that puts the sheet, the Pareto chart and the error table on one screen.
//!
//! Design notes:
//! - The page is one self-contained file: no scripts, no external assets, relative links only,
//!   so it opens from the file system, from an archive of the output folder, or from CI
//!   artifacts. Every path it names is one the caller wrote into the same folder; the page
//!   builder percent-encodes links so an output folder or file name with spaces still works.
//! - The contact sheet is an image rather than a grid of `<img>` tags so that it is one file to
//!   paste into an issue or the README, and so the shaded image and its error map sit at the
//!   same scale side by side whatever the viewer does with the page.
//! - Numbers shown in the page are formatted once by the caller ([`html::Cell`]), so the table a
//!   test parses back is the table a person reads.

pub mod contact_sheet;
pub mod html;

pub use contact_sheet::{write_contact_sheet, SheetCell};
pub use html::{Cell, Page};

/// The command line that started this process, quoted for a POSIX shell: what a report prints
/// under "made by" so it can be rerun. Arguments with characters a shell would split or expand
/// are single-quoted.
pub fn command_line() -> String {
    let mut args = std::env::args();
    // The program as `penumbra` rather than a build path, which would not rerun elsewhere.
    let program = args
        .next()
        .and_then(|p| {
            std::path::Path::new(&p)
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
        })
        .unwrap_or_else(|| "penumbra".into());
    std::iter::once(program)
        .chain(args.map(|a| shell_quote(&a)))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `arg` as one POSIX shell word.
pub fn shell_quote(arg: &str) -> String {
    let plain = !arg.is_empty()
        && arg
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,@+%".contains(c));
    if plain {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::shell_quote;

    #[test]
    fn shell_words_survive_spaces_and_quotes() {
        assert_eq!(
            shell_quote("scenes/teapot-rect.toml"),
            "scenes/teapot-rect.toml"
        );
        assert_eq!(shell_quote("out dir"), "'out dir'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote(""), "''");
    }
}
