//! One self-contained HTML page (inline CSS, the figures' SVG inlined,
//! nothing fetched): headings, paragraphs, the warnings, tables of numbers
//! and figures with captions, in the order they are added.

use std::fmt::Write as _;

const CSS: &str = "\
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:2em auto;max-width:1150px;\
padding:0 1em;color:#222;line-height:1.4}\
h1{font-size:1.6em;margin-bottom:.2em}h2{margin-top:1.8em;border-bottom:1px solid #ccc;padding-bottom:.2em}\
.headline{font-size:1.2em;background:#f3f6fa;border-left:4px solid #0072B2;padding:.6em 1em}\
.good{border-left-color:#009E73}.bad{border-left-color:#D55E00}\
ul.warnings li{margin:.3em 0}ul.warnings{border-left:4px solid #E69F00;padding:.4em 1em .4em 2em;background:#fdf8ee}\
table{border-collapse:collapse;margin:.6em 0;font-size:.95em}\
th,td{border:1px solid #d5d5d5;padding:.3em .6em;text-align:left;vertical-align:top}\
th{background:#f2f2f2}td.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}\
.muted{color:#666}figure{margin:1.5em 0;padding:.8em;border:1px solid #ddd;border-radius:4px}\
figure svg{max-width:100%;height:auto;display:block}figcaption{color:#444;font-size:.92em;margin-top:.5em}\
code{background:#f4f4f4;padding:0 .2em}";

/// `&`, `<`, `>`, `"` and `'` as HTML entities.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
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

/// One table cell.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// Text (escaped when rendered).
    Text(String),
    /// A number or a quantity, right-aligned (escaped when rendered).
    Number(String),
    /// Trusted HTML, as is (e.g. `<code>` or `<br>`), left-aligned.
    Html(String),
    /// Trusted HTML, right-aligned.
    HtmlNumber(String),
}

/// A page being built; [`Page::render`] gives the HTML document.
#[derive(Debug, Clone, PartialEq)]
pub struct Page {
    title: String,
    body: String,
    figures: usize,
}

impl Page {
    /// A page with `title` (the document title and its first heading).
    pub fn new(title: &str) -> Page {
        Page {
            title: title.to_string(),
            body: String::new(),
            figures: 0,
        }
    }

    /// A section heading.
    pub fn heading(&mut self, text: &str) -> &mut Page {
        let _ = writeln!(self.body, "<h2>{}</h2>", escape(text));
        self
    }

    /// A paragraph of plain text.
    pub fn paragraph(&mut self, text: &str) -> &mut Page {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
        self
    }

    /// A paragraph of secondary text (grey).
    pub fn note(&mut self, text: &str) -> &mut Page {
        let _ = writeln!(self.body, "<p class=\"muted\">{}</p>", escape(text));
        self
    }

    /// The headline: one sentence framed, green when `good`, vermillion
    /// when not, blue when neither is said.
    pub fn headline(&mut self, text: &str, good: Option<bool>) -> &mut Page {
        let class = match good {
            Some(true) => "headline good",
            Some(false) => "headline bad",
            None => "headline",
        };
        let _ = writeln!(self.body, "<p class=\"{class}\">{}</p>", escape(text));
        self
    }

    /// A fragment of trusted HTML, as is.
    pub fn html(&mut self, fragment: &str) -> &mut Page {
        self.body.push_str(fragment);
        if !fragment.ends_with('\n') {
            self.body.push('\n');
        }
        self
    }

    /// The warnings in plain words, one item each; `none` when there is
    /// none.
    pub fn warnings(&mut self, items: &[String], none: &str) -> &mut Page {
        if items.is_empty() {
            return self.note(none);
        }
        self.body.push_str("<ul class=\"warnings\">\n");
        for w in items {
            let _ = writeln!(self.body, "<li>{}</li>", escape(w));
        }
        self.body.push_str("</ul>\n");
        self
    }

    /// A list of plain-text items.
    pub fn list(&mut self, items: &[String]) -> &mut Page {
        self.body.push_str("<ul>\n");
        for w in items {
            let _ = writeln!(self.body, "<li>{}</li>", escape(w));
        }
        self.body.push_str("</ul>\n");
        self
    }

    /// A table: header cells, then rows of cells.
    pub fn table(&mut self, head: &[&str], rows: &[Vec<Cell>]) -> &mut Page {
        self.body.push_str("<table>\n<tr>");
        for h in head {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                let _ = match c {
                    Cell::Text(t) => write!(self.body, "<td>{}</td>", escape(t)),
                    Cell::Number(t) => write!(self.body, "<td class=\"n\">{}</td>", escape(t)),
                    Cell::Html(t) => write!(self.body, "<td>{t}</td>"),
                    Cell::HtmlNumber(t) => write!(self.body, "<td class=\"n\">{t}</td>"),
                };
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
        self
    }

    /// Name-value rows (a quantity per row, its value right-aligned).
    pub fn numbers(&mut self, rows: &[(String, String)]) -> &mut Page {
        let rows: Vec<Vec<Cell>> = rows
            .iter()
            .map(|(k, v)| vec![Cell::Text(k.clone()), Cell::Number(v.clone())])
            .collect();
        self.table(&["quantity", "value"], &rows)
    }

    /// A figure: its SVG inlined (an XML declaration dropped), a heading
    /// and a caption.
    pub fn figure(&mut self, name: &str, svg: &str, caption: &str) -> &mut Page {
        let svg = match svg.trim_start().strip_prefix("<?xml") {
            Some(rest) => rest.split_once("?>").map_or("", |r| r.1),
            None => svg,
        };
        self.figures += 1;
        let _ = writeln!(
            self.body,
            "<figure id=\"figure-{}\">\n<h3>{}</h3>",
            self.figures,
            escape(name)
        );
        self.body.push_str(svg.trim());
        let _ = writeln!(
            self.body,
            "\n<figcaption>{}</figcaption>\n</figure>",
            escape(caption)
        );
        self
    }

    /// Figures added so far.
    pub fn figure_count(&self) -> usize {
        self.figures
    }

    /// The HTML document.
    pub fn render(&self) -> String {
        let mut s = String::with_capacity(self.body.len() + 2048);
        s.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
        s.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
        let _ = writeln!(s, "<title>{}</title>", escape(&self.title));
        let _ = writeln!(s, "<style>{CSS}</style>\n</head>\n<body>");
        let _ = writeln!(s, "<h1>{}</h1>", escape(&self.title));
        s.push_str(&self.body);
        s.push_str("</body>\n</html>\n");
        s
    }
}

/// Writing to a page appends trusted HTML to its body, as [`Page::html`]
/// does (for pages with fragments of their own, e.g. lists with `<code>`).
impl std::fmt::Write for Page {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.body.push_str(s);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_page_is_self_contained_and_escapes_text() {
        let mut p = Page::new("Calibration <drive>");
        p.headline("c_RL = 1.95 m", Some(true))
            .warnings(&["a & b".to_string()], "none")
            .numbers(&[("c_RL, m".to_string(), "1.95000".to_string())])
            .figure("track", "<?xml version=\"1.0\"?>\n<svg></svg>", "the track");
        let html = p.render();
        assert!(html.starts_with("<!DOCTYPE html>"));
        assert!(html.contains("<title>Calibration &lt;drive&gt;</title>"));
        assert!(html.contains("<li>a &amp; b</li>"));
        assert!(html.contains("<td class=\"n\">1.95000</td>"));
        assert!(html.contains("<svg></svg>") && !html.contains("<?xml"));
        assert!(html.contains("<figcaption>the track</figcaption>"));
        for fetch in ["src=", "href=", "@import", "url("] {
            assert!(!html.contains(fetch), "the page fetches something: {fetch}");
        }
        assert_eq!(p.figure_count(), 1);
    }

    #[test]
    fn no_warning_says_so() {
        let mut p = Page::new("t");
        p.warnings(&[], "No warnings.");
        assert!(p.render().contains("No warnings."));
    }
}
