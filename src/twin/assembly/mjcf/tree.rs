//! An MJCF model as one tree of elements, with every `<include file="...">` replaced by the
//! children of the included file's `<mujoco>` root, as MuJoCo's parser does. Each element keeps
//! the file and line it came from, so that a refusal can name them.

use crate::error::{Error, Result};
use roxmltree::{Document, Node};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// One XML element of the model.
#[derive(Clone, Debug)]
pub struct Element {
    pub tag: String,
    attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    /// The file it was read from, and its line there.
    file: Rc<PathBuf>,
    line: u32,
    /// Whether it came from a file other than the model's own.
    included: bool,
}

impl Element {
    /// An element made here, not read (settings gathered from several elements).
    pub fn synthetic(tag: &str) -> Element {
        Element {
            tag: tag.to_string(),
            attrs: Vec::new(),
            children: Vec::new(),
            file: Rc::new(PathBuf::new()),
            line: 0,
            included: false,
        }
    }

    /// Sets (or replaces) an attribute.
    pub fn set(&mut self, name: &str, value: &str) {
        match self.attrs.iter_mut().find(|(k, _)| k == name) {
            Some(slot) => slot.1 = value.to_string(),
            None => self.attrs.push((name.to_string(), value.to_string())),
        }
    }

    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    pub fn attrs(&self) -> &[(String, String)] {
        &self.attrs
    }

    /// The element's children of one tag.
    pub fn children_named<'a>(&'a self, tag: &'a str) -> impl Iterator<Item = &'a Element> {
        self.children.iter().filter(move |c| c.tag == tag)
    }

    /// Every element below this one, depth first.
    pub fn descendants(&self) -> Vec<&Element> {
        let mut out = Vec::new();
        let mut stack: Vec<&Element> = self.children.iter().rev().collect();
        while let Some(e) = stack.pop() {
            out.push(e);
            stack.extend(e.children.iter().rev());
        }
        out
    }

    /// `<geom name="tip"> (line 12)`, or `(parts.xml line 12)` for an included file: how a
    /// message names the element.
    pub fn describe(&self) -> String {
        let name = match self.attr("name") {
            Some(n) => format!("<{} name=\"{n}\">", self.tag),
            None => format!("<{}>", self.tag),
        };
        if self.included {
            let file = self.file.file_name().unwrap_or_default().to_string_lossy();
            format!("{name} ({file} line {})", self.line)
        } else {
            format!("{name} (line {})", self.line)
        }
    }
}

/// Reads the model at `path` and the files it includes (paths relative to the model's folder,
/// as MuJoCo takes them). Errors name the file (the included one where it is at fault) and line.
pub fn read_model(path: &Path) -> Result<Element> {
    let mut chain = Vec::new();
    read_file(
        path,
        path.parent().unwrap_or(Path::new(".")),
        false,
        &mut chain,
    )
}

fn read_file(
    path: &Path,
    model_dir: &Path,
    included: bool,
    chain: &mut Vec<PathBuf>,
) -> Result<Element> {
    let text = crate::files::read_text(path)?;
    let doc =
        Document::parse(&text).map_err(|e| Error::file(path, format!("not valid XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "mujoco" {
        return Err(Error::file(
            path,
            "not an MJCF model: expected a <mujoco> root element",
        ));
    }
    chain.push(path.to_path_buf());
    let file = Rc::new(path.to_path_buf());
    let element = convert(root, &file, included, model_dir, chain);
    chain.pop();
    element
}

/// The element `node` as read, its includes expanded.
fn convert(
    node: Node,
    file: &Rc<PathBuf>,
    included: bool,
    model_dir: &Path,
    chain: &mut Vec<PathBuf>,
) -> Result<Element> {
    let mut element = Element {
        tag: node.tag_name().name().to_string(),
        attrs: node
            .attributes()
            .map(|a| (a.name().to_string(), a.value().to_string()))
            .collect(),
        children: Vec::new(),
        file: file.clone(),
        line: node.document().text_pos_at(node.range().start).row,
        included,
    };
    for child in node.children().filter(Node::is_element) {
        if child.has_tag_name("include") {
            let here = convert(child, file, included, model_dir, chain)?;
            let inner = include(&here, model_dir, chain)?;
            element.children.extend(inner.children);
        } else {
            let converted = convert(child, file, included, model_dir, chain)?;
            element.children.push(converted);
        }
    }
    Ok(element)
}

/// The `<mujoco>` root of the file an `<include>` names.
fn include(at: &Element, model_dir: &Path, chain: &mut Vec<PathBuf>) -> Result<Element> {
    let what = at.describe();
    let fail = |msg: String| Error::file(at.file.as_path(), msg);
    let name = at
        .attr("file")
        .ok_or_else(|| fail(format!("{what}: an include needs file=\"PATH\"")))?;
    let path = model_dir.join(name);
    if chain.iter().any(|p| same_file(p, &path)) {
        return Err(fail(format!(
            "{what}: file=\"{name}\" includes itself (through {})",
            chain
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(" -> ")
        )));
    }
    read_file(&path, model_dir, true, chain)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn includes_are_spliced_in_and_cycles_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("main.xml"),
            "<mujoco>\n<worldbody>\n<include file=\"parts.xml\"/>\n</worldbody>\n</mujoco>\n",
        )
        .unwrap();
        std::fs::write(
            d.join("parts.xml"),
            "<mujoco>\n\n<body name=\"peg\"><geom size=\"1\"/></body>\n</mujoco>\n",
        )
        .unwrap();
        let model = read_model(&d.join("main.xml")).unwrap();
        let world = &model.children[0];
        assert_eq!(world.children[0].tag, "body");
        assert_eq!(
            world.children[0].describe(),
            "<body name=\"peg\"> (parts.xml line 3)"
        );
        std::fs::write(
            d.join("parts.xml"),
            "<mujoco><include file=\"main.xml\"/></mujoco>",
        )
        .unwrap();
        let err = read_model(&d.join("main.xml")).unwrap_err().to_string();
        assert!(err.contains("includes itself"), "{err}");
    }
}
