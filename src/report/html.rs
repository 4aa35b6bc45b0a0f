//! A static HTML page built from a few block kinds (headings, paragraphs, images, tables,
//! preformatted text), every piece of text escaped on the way in. Deliberately small: the page
//! is a report, not an application, and a builder that can only emit escaped text and relative
//! links cannot produce a page that runs code or reaches the network.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Error, Result};

/// Minimal inline style: readable tables and images that shrink to the window.
const STYLE: &str = "body{font-family:sans-serif;margin:1.5em;max-width:1700px;color:#222}\
table{border-collapse:collapse;font-size:14px}\
th,td{border:1px solid #bbb;padding:3px 8px;text-align:right}\
th{background:#eee}td:first-child,th:first-child{text-align:left}\
tr.failed td{background:#fde8e8}tr.skipped td{background:#f2f2f2}\
img{max-width:100%;height:auto;border:1px solid #ccc}\
pre{background:#f4f4f4;padding:.6em;overflow-x:auto}\
.note{color:#555;font-size:14px}";

/// `text` with the five characters HTML gives meaning to replaced by entities.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A relative path as a link target: each segment percent-encoded except unreserved
/// characters, so spaces and `#` in file names still resolve. Absolute paths and URLs are
/// refused: a report links only to files next to it.
pub fn href(relative: &str) -> Result<String> {
    if relative.is_empty()
        || relative.starts_with('/')
        || relative.contains(':')
        || relative.split('/').any(|s| s == "..")
    {
        return Err(Error::input(
            "report::html::href",
            None,
            format!("'{relative}' is not a relative path inside the report's folder"),
        ));
    }
    let mut out = String::new();
    for b in relative.bytes() {
        if b.is_ascii_alphanumeric() || b"-_.~/".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    Ok(out)
}

/// One table cell: text, optionally a link to a file in the report's folder.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// What the cell shows (escaped when written).
    pub text: String,
    /// A relative link target, if the text links somewhere.
    pub link: Option<String>,
}

impl Cell {
    /// A plain text cell.
    pub fn text(text: impl Into<String>) -> Cell {
        Cell {
            text: text.into(),
            link: None,
        }
    }

    /// A cell linking to `target` (relative to the page).
    pub fn link(text: impl Into<String>, target: impl Into<String>) -> Cell {
        Cell {
            text: text.into(),
            link: Some(target.into()),
        }
    }
}

/// A page under construction. Blocks appear in the order they are added.
pub struct Page {
    title: String,
    body: String,
    /// Every file the page links to or shows, relative to it, for [`Page::linked_files`].
    files: Vec<String>,
}

impl Page {
    /// An empty page with `title` (also its first heading).
    pub fn new(title: &str) -> Page {
        let mut page = Page {
            title: title.to_string(),
            body: String::new(),
            files: Vec::new(),
        };
        page.heading(1, title);
        page
    }

    /// A heading of `level` 1–4.
    pub fn heading(&mut self, level: u8, text: &str) {
        let level = level.clamp(1, 4);
        let _ = writeln!(self.body, "<h{level}>{}</h{level}>", escape(text));
    }

    /// A paragraph of plain text.
    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
    }

    /// A paragraph in the smaller grey style for notes on how to read what follows.
    pub fn note(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p class=\"note\">{}</p>", escape(text));
    }

    /// Preformatted text (a command line, a device description).
    pub fn preformatted(&mut self, text: &str) {
        let _ = writeln!(self.body, "<pre>{}</pre>", escape(text));
    }

    /// An image file next to the page, linked to itself so a click opens it at full size.
    pub fn image(&mut self, src: &str, alt: &str) -> Result<()> {
        let target = href(src)?;
        let _ = writeln!(
            self.body,
            "<p><a href=\"{target}\"><img src=\"{target}\" alt=\"{}\"></a></p>",
            escape(alt)
        );
        self.files.push(src.to_string());
        Ok(())
    }

    /// A list of links to files next to the page: `(text, target)`.
    pub fn links(&mut self, links: &[(&str, &str)]) -> Result<()> {
        self.body.push_str("<ul>\n");
        for (text, target) in links {
            let _ = writeln!(
                self.body,
                "<li><a href=\"{}\">{}</a></li>",
                href(target)?,
                escape(text)
            );
            self.files.push(target.to_string());
        }
        self.body.push_str("</ul>\n");
        Ok(())
    }

    /// A table with `id`, a header row and body rows; `row_class` gives each row an optional CSS
    /// class (`failed`, `skipped`). Rows shorter than the header are padded with empty cells.
    pub fn table(
        &mut self,
        id: &str,
        header: &[&str],
        rows: &[(Option<&str>, Vec<Cell>)],
    ) -> Result<()> {
        let _ = writeln!(self.body, "<table id=\"{}\">", escape(id));
        self.body.push_str("<thead><tr>");
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr></thead>\n<tbody>\n");
        for (class, cells) in rows {
            match class {
                Some(c) => {
                    let _ = write!(self.body, "<tr class=\"{}\">", escape(c));
                }
                None => self.body.push_str("<tr>"),
            }
            for i in 0..header.len().max(cells.len()) {
                let cell = cells.get(i);
                let text = cell.map_or(String::new(), |c| escape(&c.text));
                match cell.and_then(|c| c.link.as_deref()) {
                    Some(target) => {
                        let _ = write!(
                            self.body,
                            "<td><a href=\"{}\">{text}</a></td>",
                            href(target)?
                        );
                        self.files.push(target.to_string());
                    }
                    None => {
                        let _ = write!(self.body, "<td>{text}</td>");
                    }
                }
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</tbody>\n</table>\n");
        Ok(())
    }

    /// Every file the page shows or links to, relative to it, in the order added.
    pub fn linked_files(&self) -> &[String] {
        &self.files
    }

    /// The complete document.
    pub fn finish(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
            escape(&self.title),
            self.body
        )
    }

    /// Writes the page as `path` after checking that every file it links to exists next to it:
    /// a report that points at nothing is an error here, not a broken image later.
    pub fn write(&self, path: &Path) -> Result<()> {
        let dir = path.parent().unwrap_or(Path::new("."));
        if let Some(missing) = self.files.iter().find(|f| !dir.join(f).is_file()) {
            return Err(Error::input(
                path.display().to_string(),
                None,
                format!("the page links to {missing}, which was not written"),
            ));
        }
        std::fs::write(path, self.finish()).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_links_are_encoded() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        assert_eq!(
            href("techniques/pcf/shaded image.png").expect("relative"),
            "techniques/pcf/shaded%20image.png"
        );
        for bad in ["/etc/passwd", "../x.png", "http://example.com/x.png", ""] {
            assert!(href(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn tables_pad_rows_and_remember_their_links() {
        let mut page = Page::new("t <1>");
        page.table(
            "errors",
            &["technique", "ms"],
            &[
                (
                    None,
                    vec![Cell::link("pcf", "pcf/shaded.png"), Cell::text("1.5")],
                ),
                (Some("failed"), vec![Cell::text("vsm")]),
            ],
        )
        .expect("table");
        let html = page.finish();
        assert!(html.contains("<title>t &lt;1&gt;</title>"));
        assert!(html.contains("<tr class=\"failed\"><td>vsm</td><td></td></tr>"));
        assert_eq!(page.linked_files(), ["pcf/shaded.png".to_string()]);
    }
}
