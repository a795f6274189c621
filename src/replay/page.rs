//! A replay as one self-contained HTML page: the viewer's page and script (`viewer/`, embedded
//! at build time) with the recording inlined as JSON. Arrays travel as base64 of little-endian
//! `f32` (positions, poses, wrenches), `u32` (triangle indices) and `u8` (phases, contact
//! flags); a pose is `[x, y, z, qx, qy, qz, qw]` in the base frame, m. The format is the
//! viewer's own (`viewer/README.md`), versioned by `format`.

use super::scene::Mesh;
use super::{FRAME_DT_S, PHASES, Replay};
use crate::method::trial::TrialResult;
use crate::pose::Iso;
use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use serde_json::{Value, json};

/// The viewer's page, with the markers below where the data and the script go.
const PAGE: &str = include_str!("../../viewer/replay.html");
/// The viewer's script (our own WebGL renderer and controls).
const SCRIPT: &str = include_str!("../../viewer/replay.js");
const DATA_MARKER: &str = "__PEGTWIN_REPLAY_DATA__";
const SCRIPT_MARKER: &str = "__PEGTWIN_REPLAY_SCRIPT__";
const TITLE_MARKER: &str = "__PEGTWIN_REPLAY_TITLE__";
const PANEL_MARKER: &str = "__PEGTWIN_REGISTRATION_PANEL__";
/// The version of the data format the viewer reads.
pub const FORMAT: u32 = 1;

/// The page of `replay` for the trial that gave `result`, with the registration panel (a PNG
/// image) when there is one.
pub fn html(replay: &Replay, result: &TrialResult, panel: Option<&[u8]>) -> String {
    let title = title(result);
    let data = payload(replay, result, &title).to_string();
    // Inside a <script> element only "</" could end it early; "<\/" is the same JSON string.
    let data = data.replace("</", "<\\/");
    let panel = panel.map_or(String::new(), |png| {
        format!(
            "<details id=\"registration\" open><summary>Registration (paper IV-D)</summary>\
             <img alt=\"contact poses before and after registration over the manifold\" \
             src=\"data:image/png;base64,{}\"></details>",
            STANDARD.encode(png)
        )
    });
    PAGE.replace(TITLE_MARKER, &escape(&title))
        .replace(PANEL_MARKER, &panel)
        .replace(DATA_MARKER, &data)
        .replace(SCRIPT_MARKER, SCRIPT)
}

/// The page's title: what the trial was and how it ended.
fn title(r: &TrialResult) -> String {
    format!(
        "{} at {} mm, {:?}, seed {}: {}",
        r.geometry, r.clearance_mm, r.method, r.seed, r.outcome
    )
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The recording as the viewer reads it.
fn payload(replay: &Replay, result: &TrialResult, title: &str) -> Value {
    let scene = &replay.scene;
    let frames = &replay.frames;
    let links: Vec<Value> = scene
        .links
        .iter()
        .map(|(name, mesh)| json!({ "name": name, "mesh": mesh_json(mesh) }))
        .collect();
    let estimate = replay.registration.as_ref().and_then(|r| r.estimate);
    json!({
        "format": FORMAT,
        "title": title,
        "trial": result,
        "robot": scene.robot_name,
        "geometry": scene.geometry,
        "clearance_m": scene.clearance_m,
        "frame_dt_s": FRAME_DT_S,
        "phases": PHASES.map(|p| p.name()),
        "links": links,
        "peg": mesh_json(&scene.peg),
        "hole": mesh_json(&scene.hole),
        "true_hole": replay.true_hole.as_ref().map(pose7),
        "estimated_hole": estimate.as_ref().map(pose7),
        "frames": {
            "count": frames.len(),
            "time_s": f32s(frames.iter().map(|f| f.time_s)),
            "phase": bytes(frames.iter().map(|f| phase_index(f.phase))),
            "contact": bytes(frames.iter().map(|f| u8::from(f.contact))),
            "links": f32s(frames.iter().flat_map(|f| f.links.iter().flat_map(pose7))),
            "peg": f32s(frames.iter().flat_map(|f| pose7(&f.peg))),
            "est_wrench": f32s(frames.iter().flat_map(|f| f.est_wrench)),
            "true_wrench": f32s(frames.iter().flat_map(|f| f.true_wrench)),
        },
    })
}

fn phase_index(phase: crate::method::session::Phase) -> u8 {
    PHASES.iter().position(|p| *p == phase).unwrap_or(0) as u8
}

/// A pose as `[x, y, z, qx, qy, qz, qw]`.
fn pose7(t: &Iso) -> [f64; 7] {
    let (p, q) = (t.translation.vector, t.rotation.coords);
    [p.x, p.y, p.z, q.x, q.y, q.z, q.w]
}

fn mesh_json(mesh: &Mesh) -> Value {
    let indices: Vec<u8> = mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect();
    json!({
        "positions": f32s(mesh.positions.iter().map(|&v| v as f64)),
        "indices": STANDARD.encode(indices),
    })
}

/// Base64 of the values as little-endian `f32`.
fn f32s(values: impl Iterator<Item = f64>) -> String {
    let raw: Vec<u8> = values.flat_map(|v| (v as f32).to_le_bytes()).collect();
    STANDARD.encode(raw)
}

fn bytes(values: impl Iterator<Item = u8>) -> String {
    STANDARD.encode(values.collect::<Vec<u8>>())
}
