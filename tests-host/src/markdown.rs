//! Markdown files the report programs (`cycle-budget`, `scale`) write into: one section
//! replaced in place.

/// Replaces the section starting at `heading` (up to the next `## ` heading) in the
/// Markdown file `path`, or appends it.
pub fn replace_section(path: &str, heading: &str, body: &str) -> std::io::Result<()> {
    let old = std::fs::read_to_string(path).unwrap_or_default();
    let mut out = String::new();
    let mut lines = old.lines().peekable();
    let mut done = false;
    while let Some(l) = lines.next() {
        if l.trim_end() == heading {
            out.push_str(body.trim_end());
            out.push_str("\n\n");
            while lines.peek().is_some_and(|n| !n.starts_with("## ")) {
                lines.next();
            }
            done = true;
            continue;
        }
        out.push_str(l);
        out.push('\n');
    }
    if !done {
        if !out.is_empty() && !out.ends_with("\n\n") {
            out.push('\n');
        }
        out.push_str(body.trim_end());
        out.push('\n');
    }
    std::fs::write(path, out.trim_end().to_string() + "\n")
}
