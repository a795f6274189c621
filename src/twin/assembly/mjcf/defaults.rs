//! MJCF default classes: `<default>` (the class `main`) and the classes nested in it, each
//! inheriting its parent's attributes; an element takes the class it names (`class=`), else the
//! `childclass` of the nearest enclosing body or frame, else `main`. Its own attributes win,
//! and giving any orientation (`quat`, `axisangle`, `xyaxes`, `zaxis`, `euler`) replaces the
//! class's orientation, as in MuJoCo; a `size` of fewer numbers than the class's replaces only
//! the leading ones.

use super::tree::Element;
use std::collections::HashMap;

/// The attributes MuJoCo reads as an orientation: at most one of them per element.
pub const ORIENTATIONS: [&str; 5] = ["quat", "axisangle", "xyaxes", "zaxis", "euler"];

/// Every default class of a model, by name: its parent and the attributes it sets per tag.
#[derive(Debug, Default)]
pub struct Defaults {
    classes: HashMap<String, Class>,
}

#[derive(Debug, Default)]
struct Class {
    parent: Option<String>,
    /// Per element tag (`geom`, `mesh`), the attributes this class sets.
    by_tag: HashMap<String, Vec<(String, String)>>,
}

impl Defaults {
    /// The classes of the model's `<default>` sections.
    pub fn read(model: &Element) -> Result<Defaults, String> {
        let mut defaults = Defaults::default();
        defaults.classes.insert("main".into(), Class::default());
        for top in model.children_named("default") {
            let name = top.attr("class").unwrap_or("main").to_string();
            defaults.add(top, name, None)?;
        }
        Ok(defaults)
    }

    fn add(&mut self, at: &Element, name: String, parent: Option<String>) -> Result<(), String> {
        if parent.is_some() && self.classes.contains_key(&name) {
            return Err(format!(
                "{}: class=\"{name}\" is defined twice",
                at.describe()
            ));
        }
        let class = self.classes.entry(name.clone()).or_default();
        class.parent = class.parent.take().or(parent);
        for child in at.children.iter().filter(|c| c.tag != "default") {
            let set = class.by_tag.entry(child.tag.clone()).or_default();
            overlay(set, child.attrs());
        }
        for nested in at.children_named("default") {
            let inner = nested.attr("class").ok_or_else(|| {
                format!(
                    "{}: a nested default needs class=\"NAME\"",
                    nested.describe()
                )
            })?;
            self.add(nested, inner.to_string(), Some(name.clone()))?;
        }
        Ok(())
    }

    /// The attributes of `element` as MuJoCo resolves them: those of its class (`class=`, else
    /// `childclass`, else `main`) and its parents', overlaid by its own.
    pub fn resolve(&self, element: &Element, childclass: Option<&str>) -> Result<Attrs, String> {
        let class = element.attr("class").or(childclass).unwrap_or("main");
        let mut chain = Vec::new();
        let mut at = Some(class.to_string());
        while let Some(name) = at {
            let c = self.classes.get(&name).ok_or_else(|| {
                format!(
                    "{}: class=\"{name}\": no <default class=\"{name}\"> in the model",
                    element.describe()
                )
            })?;
            chain.push(c.by_tag.get(&element.tag));
            at = c.parent.clone();
        }
        let mut attrs = Vec::new();
        for set in chain.into_iter().rev().flatten() {
            overlay(&mut attrs, set);
        }
        overlay(&mut attrs, element.attrs());
        Ok(Attrs {
            what: element.describe(),
            list: attrs,
        })
    }

    /// Whether a class of this name exists (for `childclass=`).
    pub fn has(&self, name: &str) -> bool {
        self.classes.contains_key(name)
    }
}

/// An element's attributes as resolved, with how messages name the element.
#[derive(Clone, Debug)]
pub struct Attrs {
    pub what: String,
    list: Vec<(String, String)>,
}

impl Attrs {
    /// The element's own attributes (an element no default class applies to: a body, a frame).
    pub fn own(element: &Element) -> Attrs {
        Attrs {
            what: element.describe(),
            list: element.attrs().to_vec(),
        }
    }

    pub fn get(&self, name: &str) -> Option<&str> {
        self.list
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// A message about attribute `name` of the element.
    pub fn fail(&self, name: &str, msg: impl std::fmt::Display) -> String {
        match self.get(name) {
            Some(v) => format!("{}: {name}=\"{v}\": {msg}", self.what),
            None => format!("{}: {name}: {msg}", self.what),
        }
    }
}

/// `base` with `over`'s attributes set on it; an orientation in `over` replaces `base`'s.
fn overlay(base: &mut Vec<(String, String)>, over: &[(String, String)]) {
    if over.iter().any(|(k, _)| ORIENTATIONS.contains(&k.as_str())) {
        base.retain(|(k, _)| !ORIENTATIONS.contains(&k.as_str()));
    }
    for (k, v) in over {
        match base.iter_mut().find(|(bk, _)| bk == k) {
            Some(slot) if k == "size" => slot.1 = leading_replaced(&slot.1, v),
            Some(slot) => slot.1 = v.clone(),
            None => base.push((k.clone(), v.clone())),
        }
    }
}

/// `size` given in part keeps the class's later numbers, as MuJoCo reads it ("0.01" over
/// "0.005 0.02" is "0.01 0.02").
fn leading_replaced(base: &str, over: &str) -> String {
    let given: Vec<&str> = over.split_whitespace().collect();
    let kept = base.split_whitespace().skip(given.len());
    given.into_iter().chain(kept).collect::<Vec<_>>().join(" ")
}
