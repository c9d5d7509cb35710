//! A small static HTML page builder: escaped text, tables, images beside
//! the page, inline CSS, no scripts and no external links.

use std::fmt::Write as _;
use std::path::PathBuf;

use alacs_model::io::OutputDir;

use crate::Result;

/// The page's style sheet, inline so that the page is self-contained.
const STYLE: &str = "\
body{font-family:sans-serif;margin:1.5em auto;max-width:80em;padding:0 1em;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.2em .5em;text-align:right}\
th{background:#f2f2f2}td.l,th.l{text-align:left}tr.bad td{background:#fde2e2}\
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(26em,1fr));gap:1em}\
figure{margin:0;border:1px solid #ccc;padding:.4em}figure.bad{border:2px solid #c00}\
figure img{width:100%;height:auto;display:block}figcaption{font-size:.9em;margin-top:.3em}\
img.plot{max-width:100%;height:auto}.flag{color:#c00;font-weight:bold}.note{color:#555;font-size:.9em}\
.legend span{display:inline-block;margin-right:1.2em}";

/// Escapes `text` for HTML text and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A table cell: text (escaped when written), left- or right-aligned.
pub struct Cell {
    text: String,
    left: bool,
}

/// A right-aligned cell (numbers).
pub fn num(text: impl Into<String>) -> Cell {
    Cell { text: text.into(), left: false }
}

/// A left-aligned cell (names, reasons).
pub fn txt(text: impl Into<String>) -> Cell {
    Cell { text: text.into(), left: true }
}

/// A number with `digits` decimals, or a dash for none.
pub fn fixed(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.digits$}"),
        _ => "-".to_string(),
    }
}

/// The body of a page being built.
pub struct Page {
    body: String,
}

impl Page {
    /// A page titled `title` (escaped).
    pub fn new(title: &str) -> Self {
        let mut page = Self { body: String::new() };
        let _ = writeln!(page.body, "<h1>{}</h1>", escape(title));
        page
    }

    /// A section heading.
    pub fn heading(&mut self, text: &str) {
        let _ = writeln!(self.body, "<h2>{}</h2>", escape(text));
    }

    /// A paragraph of escaped text, with `class` if given.
    pub fn paragraph(&mut self, text: &str, class: Option<&str>) {
        match class {
            Some(class) => {
                let _ = writeln!(self.body, "<p class=\"{class}\">{}</p>", escape(text));
            }
            None => {
                let _ = writeln!(self.body, "<p>{}</p>", escape(text));
            }
        }
    }

    /// Raw markup (the caller escapes what it holds).
    pub fn raw(&mut self, markup: &str) {
        self.body.push_str(markup);
        self.body.push('\n');
    }

    /// A table; rows whose flag is set are highlighted.
    pub fn table(&mut self, header: &[Cell], rows: &[(Vec<Cell>, bool)]) {
        self.body.push_str("<table>\n<tr>");
        for cell in header {
            let class = if cell.left { " class=\"l\"" } else { "" };
            let _ = write!(self.body, "<th{class}>{}</th>", escape(&cell.text));
        }
        self.body.push_str("</tr>\n");
        for (row, bad) in rows {
            self.body.push_str(if *bad { "<tr class=\"bad\">" } else { "<tr>" });
            for cell in row {
                let class = if cell.left { " class=\"l\"" } else { "" };
                let _ = write!(self.body, "<td{class}>{}</td>", escape(&cell.text));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// A plot (a file beside the page, `src` relative to it).
    pub fn plot(&mut self, src: &str, alt: &str) {
        let _ = writeln!(
            self.body,
            "<p><a href=\"{0}\"><img class=\"plot\" src=\"{0}\" alt=\"{1}\"></a></p>",
            escape(src),
            escape(alt)
        );
    }

    /// Starts a grid of figures.
    pub fn grid_start(&mut self) {
        self.body.push_str("<div class=\"grid\">\n");
    }

    /// Ends a grid of figures.
    pub fn grid_end(&mut self) {
        self.body.push_str("</div>\n");
    }

    /// A figure: images (relative `src`) and an escaped caption; a flagged
    /// figure is framed in red with `flag` in its caption.
    pub fn figure(&mut self, sources: &[&str], caption: &str, flag: Option<&str>) {
        let linked: Vec<(&str, &str)> = sources.iter().map(|s| (*s, *s)).collect();
        self.linked_figure(&linked, caption, flag);
    }

    /// [`Self::figure`] with each image (`src`, first) linking to another
    /// file (second: e.g. the full-size image).
    pub fn linked_figure(&mut self, sources: &[(&str, &str)], caption: &str, flag: Option<&str>) {
        let class = if flag.is_some() { " class=\"bad\"" } else { "" };
        let _ = write!(self.body, "<figure{class}>");
        for (src, target) in sources {
            let _ = write!(
                self.body,
                "<a href=\"{1}\"><img src=\"{0}\" alt=\"{0}\" loading=\"lazy\"></a>",
                escape(src),
                escape(target)
            );
        }
        let _ = write!(self.body, "<figcaption>{}", escape(caption));
        if let Some(flag) = flag {
            let _ = write!(self.body, "<br><span class=\"flag\">{}</span>", escape(flag));
        }
        self.body.push_str("</figcaption></figure>\n");
    }

    /// Writes the page to `index.html` in `out`; returns its path.
    pub fn write(&self, out: &mut OutputDir, title: &str) -> Result<PathBuf> {
        let html = format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
            escape(title),
            self.body
        );
        Ok(out.write("index.html", html)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_quotes() {
        assert_eq!(
            escape("<a href=\"x\">'&'</a>"),
            "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;"
        );
    }
}
