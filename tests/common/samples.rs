// The code samples of the README and the docs, so that every one of them is run.
//
// A sample is a fenced block in a language the tests run (`rust`, `python`, `c`, `csharp`,
// `js`). An HTML comment right above the fence, invisible where the Markdown is read, gives what
// the sample leaves out (its inputs, a `main`):
//
//     <!-- sample setup:
//     let engine = Engine::new();
//     -->
//
// or why the sample cannot run here (`<!-- sample skip: needs a running gateway -->`), which the
// runner reports as a counted skip. `build.rs` turns the Rust samples into doc tests; the tests
// of each binding run the others. Plain `//` comments: `build.rs` includes this file.

/// One fenced code block of a Markdown file.
#[derive(Debug, Clone)]
pub struct Sample {
    /// The file, relative to the repository root.
    pub file: String,
    /// The line of the opening fence (1-based).
    pub line: usize,
    /// The code as written.
    pub code: String,
    /// What the setup comment above it gives ("" without one).
    pub setup: String,
    /// Why it is not run, from a skip comment.
    pub skip: Option<String>,
}

/// The Markdown files whose samples are run: the README, `docs/`, each binding's README.
pub fn sample_files(root: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut files = vec![root.join("README.md")];
    for dir in ["docs", "bindings/csharp", "unity", "onnx"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut found: Vec<_> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "md"))
            .collect();
        found.sort();
        files.extend(found);
    }
    files
}

/// The samples in `lang` of every file [`sample_files`] lists, in order.
pub fn samples(root: &std::path::Path, lang: &str) -> Vec<Sample> {
    let mut out = Vec::new();
    for path in sample_files(root) {
        let text = std::fs::read_to_string(&path).unwrap_or_default();
        let file = path
            .strip_prefix(root)
            .unwrap_or(&path)
            .to_string_lossy()
            .into_owned();
        out.extend(samples_in(&file, &text, lang));
    }
    out
}

/// The samples in `lang` of one Markdown text.
pub fn samples_in(file: &str, text: &str, lang: &str) -> Vec<Sample> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let (mut setup, mut skip) = (String::new(), None);
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim_end();
        if let Some(rest) = line.strip_prefix("<!-- sample setup:") {
            // The setup runs to the closing `-->`, on its own line or the comment's.
            setup.clear();
            let mut body = vec![rest];
            while !body.last().is_some_and(|l| l.trim_end().ends_with("-->")) && i + 1 < lines.len()
            {
                i += 1;
                body.push(lines[i]);
            }
            for l in body {
                let l = l.trim_end().strip_suffix("-->").unwrap_or(l.trim_end());
                if !l.trim().is_empty() {
                    setup.push_str(l);
                    setup.push('\n');
                }
            }
        } else if let Some(rest) = line.strip_prefix("<!-- sample skip:") {
            skip = Some(rest.trim().trim_end_matches("-->").trim().to_string());
        } else if let Some(fence) = line.strip_prefix("```") {
            let start = i;
            let mut code = String::new();
            i += 1;
            while i < lines.len() && !lines[i].trim_end().starts_with("```") {
                code.push_str(lines[i]);
                code.push('\n');
                i += 1;
            }
            if fence.trim() == lang {
                out.push(Sample {
                    file: file.to_string(),
                    line: start + 1,
                    code,
                    setup: std::mem::take(&mut setup),
                    skip: skip.take(),
                });
            }
            setup.clear();
            skip = None;
        } else if !line.trim().is_empty() {
            // A setup belongs to the block right below it, blank lines between at most.
            setup.clear();
            skip = None;
        }
        i += 1;
    }
    out
}
