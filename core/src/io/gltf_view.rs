//! A glTF file's view: its first camera and its directional lights (`KHR_lights_punctual`),
//! read as the document camera and Thicket lights, and the import report's lines about them.
//!
//! Reads only the deserialized JSON (every index through `get`) and the world transforms the
//! reader already computed for the scene's nodes, so it cannot fail or panic on any file the
//! readers accept: a camera or light it cannot use is said in a report line and left out.

use glam::{Mat4, Vec3};
use gltf::json;
use gltf::json::validation::Checked;

use crate::scene::{Document, Light, OrbitCamera};

/// The extension for lights.
const LIGHTS: &str = "KHR_lights_punctual";

/// A roll (rotation about the view axis) below this many degrees is not reported: the
/// exporter's own cameras carry float noise only.
const ROLL_REPORTED_DEG: f32 = 0.5;

/// The field of view an orthographic camera is given (glTF stores none): the view's height is
/// kept exactly through the distance, `ymag = distance · tan(fov / 2)`.
const ORTHO_FOV_Y_DEG: f32 = 45.0;

/// A glTF camera placed by a node of the scene, in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GltfCamera {
    /// The camera node's world position.
    pub eye: Vec3,
    /// Unit direction the camera looks along (its node's world −Z).
    pub forward: Vec3,
    /// Vertical field of view in degrees (perspective cameras).
    pub fov_y_deg: f32,
    /// Near clip distance (glTF `znear`).
    pub znear: f32,
    /// Far clip distance (glTF `zfar`; `None` for an infinite perspective projection).
    pub zfar: Option<f32>,
    /// Half the view height of an orthographic camera (glTF `ymag`).
    pub ortho_half_height: Option<f32>,
}

impl GltfCamera {
    /// The document camera showing the same view: eye at the node, yaw and pitch from its
    /// forward axis (roll is dropped; the report says so), the target on the view axis.
    ///
    /// The orbit distance is not stored in glTF: a perspective camera's target is the centre
    /// of `bounds` (the imported model's) projected on the view axis, where the exporter puts
    /// it when the view was framed on the model; with the model behind the camera or no model,
    /// the geometric mean of near and far (or 10 × near for an infinite far plane). An
    /// orthographic camera's distance is what keeps its height at a 45° field of view:
    /// `ymag / tan(22.5°)`.
    #[must_use]
    pub fn orbit_camera(&self, bounds: Option<(Vec3, Vec3)>) -> OrbitCamera {
        let back = -self.forward;
        let pitch_deg = back.y.clamp(-1.0, 1.0).asin().to_degrees();
        let yaw_deg = if back.x.abs() + back.z.abs() < 1e-6 {
            0.0
        } else {
            back.x.atan2(back.z).to_degrees()
        };
        let near = self.znear;
        let mut camera = OrbitCamera {
            yaw_deg,
            pitch_deg,
            near,
            ..OrbitCamera::default()
        };
        match self.ortho_half_height {
            Some(half_height) => {
                camera.orthographic = true;
                camera.fov_y_deg = ORTHO_FOV_Y_DEG;
                camera.distance = half_height / (ORTHO_FOV_Y_DEG.to_radians() * 0.5).tan();
                camera.far = self
                    .zfar
                    .filter(|&f| f > near)
                    .unwrap_or(near + camera.distance * 100.0);
            }
            None => {
                camera.fov_y_deg = self.fov_y_deg;
                let along = bounds
                    .map(|(lo, hi)| ((lo + hi) * 0.5 - self.eye).dot(self.forward))
                    .filter(|d| d.is_finite() && *d > near);
                let fallback = self.zfar.map_or(near * 10.0, |far| (near * far).sqrt());
                camera.distance = along.unwrap_or(fallback).max(near * 1.001);
                camera.far = self
                    .zfar
                    .unwrap_or_else(|| (camera.distance * 100.0).max(near * 1e4));
            }
        }
        camera.target = self.eye + self.forward * camera.distance;
        camera
    }
}

/// What a glTF file holds for the view: its first camera and its directional lights.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GltfView {
    /// The first camera placed by a node of the scene (depth-first, in node order).
    pub camera: Option<GltfCamera>,
    /// The directional lights placed by nodes of the scene, in the same order. The strongest
    /// (intensity × brightest colour channel; the first of equals) casts shadows, the others
    /// do not: the renderer's shadow map serves one sun well.
    pub lights: Vec<Light>,
}

impl GltfView {
    /// Applies the view to a document made from this file: its lights replace the document's
    /// when it has at least one, its camera replaces the document's (placed against the
    /// document's bounds, see [`GltfCamera::orbit_camera`]).
    pub fn apply_to_new_document(&self, doc: &mut Document) {
        if !self.lights.is_empty() {
            doc.lights.clone_from(&self.lights);
        }
        if let Some(c) = &self.camera {
            let camera = c.orbit_camera(doc.bounds());
            if camera.validate().is_ok() {
                doc.camera = camera;
            }
        }
    }

    /// Adds the file's lights to an existing document's, keeping the document's view. None of
    /// them casts shadows when the document already has a light that does.
    pub fn add_lights_to(&self, doc: &mut Document) {
        let added = self.lights_beside(&doc.lights);
        doc.lights.extend(added);
    }

    /// The file's lights as they join `existing`: none casts shadows when one of `existing`
    /// does (the renderer's shadow map serves one sun well).
    #[must_use]
    pub fn lights_beside(&self, existing: &[Light]) -> Vec<Light> {
        let has_shadows = existing.iter().any(|l| l.casts_shadows);
        self.lights
            .iter()
            .cloned()
            .map(|mut l| {
                l.casts_shadows &= !has_shadows;
                l
            })
            .collect()
    }
}

/// The file's view and the report lines about its cameras and lights (each said once):
/// "N camera(s): the first imported as the document camera", a dropped roll, and
/// "lights: N directional imported, M point/spot not imported".
///
/// `scene_nodes` are the scene's nodes with their world transforms, as the readers list them.
pub(crate) fn read_view(
    root: &json::Root,
    scene_nodes: &[(usize, Mat4)],
) -> (GltfView, Vec<String>) {
    let mut view = GltfView::default();
    let mut lines = Vec::new();
    let defs = root
        .extensions
        .as_ref()
        .and_then(|e| e.others.get(LIGHTS))
        .and_then(|l| l.get("lights"))
        .and_then(|l| l.as_array());
    let mut unusable = 0usize;
    let mut placed = vec![false; defs.map_or(0, Vec::len)];
    let mut first_camera: Option<(usize, Mat4)> = None;
    for &(index, world_from_node) in scene_nodes {
        let Some(node) = root.nodes.get(index) else {
            continue;
        };
        if first_camera.is_none()
            && let Some(c) = node.camera
            && root.cameras.get(c.value()).is_some()
        {
            first_camera = Some((c.value(), world_from_node));
        }
        let Some((def_index, def)) = node
            .extensions
            .as_ref()
            .and_then(|e| e.others.get(LIGHTS))
            .and_then(|l| l.get("light"))
            .and_then(serde_json::Value::as_u64)
            .and_then(|i| usize::try_from(i).ok())
            .and_then(|i| Some((i, defs?.get(i)?)))
        else {
            continue;
        };
        placed[def_index] = true;
        if is_directional(def) {
            match directional(def, index, node, world_from_node) {
                Some(light) => view.lights.push(light),
                None => unusable += 1,
            }
        }
    }
    // The strongest light casts shadows.
    let strength = |l: &Light| l.intensity * l.color.max_element();
    let strongest = view
        .lights
        .iter()
        .enumerate()
        .fold(None::<(usize, f32)>, |best, (i, l)| match best {
            Some((_, s)) if s >= strength(l) => best,
            _ => Some((i, strength(l))),
        })
        .map(|b| b.0);
    for (i, l) in view.lights.iter_mut().enumerate() {
        l.casts_shadows = Some(i) == strongest;
    }

    if !root.cameras.is_empty() {
        match first_camera.and_then(|(c, m)| camera(root, c, m).map(|cam| (c, cam))) {
            Some((c, (cam, roll_deg))) => {
                lines.push(format!(
                    "{} camera(s): the first imported as the document camera ({})",
                    root.cameras.len(),
                    camera_name(root, c)
                ));
                if roll_deg.abs() > ROLL_REPORTED_DEG {
                    lines.push(format!(
                        "camera {}: its roll of {roll_deg:.1}° is dropped (the document camera \
                         keeps the world's +Y up)",
                        camera_name(root, c)
                    ));
                }
                view.camera = Some(cam);
            }
            None => lines.push(format!(
                "{} camera(s): not imported, none is placed by a node of the scene with a usable \
                 projection; the view is framed on the model",
                root.cameras.len()
            )),
        }
    }
    if let Some(defs) = defs.filter(|d| !d.is_empty()) {
        let point_spot = defs.iter().filter(|d| !is_directional(d)).count();
        let unplaced = defs
            .iter()
            .zip(&placed)
            .filter(|(d, p)| is_directional(d) && !**p)
            .count();
        let mut line = format!(
            "lights: {} directional imported, {point_spot} point/spot not imported (Thicket \
             lights are directional)",
            view.lights.len()
        );
        if unplaced > 0 {
            line.push_str(&format!(
                "; {unplaced} directional not placed by any node of the scene"
            ));
        }
        if unusable > 0 {
            line.push_str(&format!(
                "; {unusable} directional with an unusable colour or intensity"
            ));
        }
        lines.push(line);
    }
    (view, lines)
}

fn is_directional(def: &serde_json::Value) -> bool {
    def.get("type").and_then(|t| t.as_str()) == Some("directional")
}

fn camera_name(root: &json::Root, index: usize) -> String {
    root.cameras
        .get(index)
        .and_then(|c| c.name.clone())
        .map_or_else(|| format!("camera {index}"), |n| format!("{n:?}"))
}

/// Camera `index` placed by `world_from_node`, and its roll in degrees; `None` when its
/// projection is missing or unusable.
fn camera(root: &json::Root, index: usize, world_from_node: Mat4) -> Option<(GltfCamera, f32)> {
    let c = root.cameras.get(index)?;
    let (_, rotation, eye) = world_from_node.to_scale_rotation_translation();
    if !(rotation.is_finite() && rotation.length() > 1e-6) {
        return None;
    }
    let rotation = rotation / rotation.length();
    let forward = (rotation * Vec3::NEG_Z).try_normalize()?;
    let up = rotation * Vec3::Y;
    let out = match (&c.type_, &c.perspective, &c.orthographic) {
        (Checked::Valid(json::camera::Type::Orthographic), _, Some(o)) => GltfCamera {
            eye,
            forward,
            fov_y_deg: ORTHO_FOV_Y_DEG,
            znear: o.znear,
            zfar: Some(o.zfar),
            ortho_half_height: Some(o.ymag.abs()),
        },
        (Checked::Valid(json::camera::Type::Perspective), Some(p), _) => GltfCamera {
            eye,
            forward,
            fov_y_deg: p.yfov.to_degrees(),
            znear: p.znear,
            zfar: p.zfar,
            ortho_half_height: None,
        },
        _ => return None,
    };
    let usable = out.eye.is_finite()
        && out.fov_y_deg > 0.1
        && out.fov_y_deg < 179.0
        && out.znear.is_finite()
        && out.zfar.is_none_or(|f| f.is_finite() && f > out.znear)
        && out
            .ortho_half_height
            .is_none_or(|h| h.is_finite() && h > 0.0)
        && (out.ortho_half_height.is_some() || out.znear > 0.0);
    if !usable {
        return None;
    }
    // The up an orbit camera would have with this forward (none when looking straight up or
    // down, where any roll is a yaw).
    let roll_deg = forward
        .cross(Vec3::Y)
        .try_normalize()
        .filter(|_| forward.y.abs() < 0.999)
        .map_or(0.0, |right| {
            let level_up = right.cross(forward);
            // Positive counter-clockwise about the camera's own +Z, as a glTF node turns.
            (-up.dot(right)).atan2(up.dot(level_up)).to_degrees()
        });
    Some((out, roll_deg))
}

/// A directional light definition placed by `world_from_node` (it shines along the node's
/// world −Z), or `None` when its direction, colour or intensity is unusable.
fn directional(
    def: &serde_json::Value,
    index: usize,
    node: &json::Node,
    world_from_node: Mat4,
) -> Option<Light> {
    let (_, rotation, _) = world_from_node.to_scale_rotation_translation();
    let direction = (rotation * Vec3::NEG_Z).try_normalize()?;
    let color = match def.get("color").and_then(|c| c.as_array()) {
        Some(c) if c.len() == 3 => {
            let v: Vec<f32> = c
                .iter()
                .filter_map(|x| x.as_f64())
                .map(|x| x as f32)
                .collect();
            (v.len() == 3).then(|| Vec3::new(v[0], v[1], v[2]))?
        }
        Some(_) => return None,
        None => Vec3::ONE,
    };
    let intensity = match def.get("intensity") {
        Some(i) => i.as_f64()? as f32,
        None => 1.0,
    };
    let name = def
        .get("name")
        .and_then(|n| n.as_str())
        .map(str::to_owned)
        .or_else(|| node.name.clone())
        .unwrap_or_else(|| format!("light {index}"));
    let light = Light {
        name,
        direction,
        color,
        intensity,
        casts_shadows: false,
    };
    light.validate().is_ok().then_some(light)
}

#[cfg(test)]
mod tests {
    use glam::{Quat, UVec3};

    use super::*;
    use crate::io::ImportLimits;
    use crate::io::gltf_export::{GltfExportOptions, export_gltf};
    use crate::scene::{MeshObject, ObjectKind, VoxelModel};
    use crate::svo::{Svo, Voxel};

    /// A document with a 4×3×2-voxel block off the origin, a camera framed on it from
    /// `yaw`, `pitch` and `fov`, and two lights: a sun and a dim blue fill.
    fn lit_document(yaw_deg: f32, pitch_deg: f32, fov_y_deg: f32) -> Document {
        let mut svo = Svo::new(3, false).unwrap();
        for (x, y, z) in
            (0..4).flat_map(|x| (0..3).flat_map(move |y| (0..2).map(move |z| (x, y, z))))
        {
            svo.set(
                UVec3::new(x, y, z),
                Voxel::new([200, 120, 60, 255], Vec3::Y),
            )
            .unwrap();
        }
        let mut doc = Document::default();
        doc.add(
            "block",
            ObjectKind::Voxels(VoxelModel {
                svo,
                voxel_size: 0.25,
                origin: Vec3::new(1.0, -0.5, 2.0),
                material_names: vec!["clay".into()],
                rig: None,
                volume: None,
                palette: Vec::new(),
                frames: None,
            }),
        );
        doc.camera.yaw_deg = yaw_deg;
        doc.camera.pitch_deg = pitch_deg;
        doc.camera.fov_y_deg = fov_y_deg;
        let (lo, hi) = doc.bounds().unwrap();
        doc.camera.frame(lo, hi);
        doc.lights = vec![
            Light {
                name: "Sun".into(),
                direction: Vec3::new(-0.4, -1.0, -0.3),
                color: Vec3::new(1.0, 0.95, 0.9),
                intensity: 2.5,
                casts_shadows: true,
            },
            Light {
                name: "Fill".into(),
                direction: Vec3::new(0.7, -0.2, 0.5),
                color: Vec3::new(0.5, 0.6, 1.0),
                intensity: 0.3,
                casts_shadows: false,
            },
        ];
        doc
    }

    /// Exports `doc` to a .glb and makes a new document from it, as opening the file does:
    /// one mesh object, then the file's view.
    fn round_trip(doc: &Document) -> (Document, Vec<String>) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("view.glb");
        let report =
            export_gltf(doc, &path, &GltfExportOptions::default(), &|_| true).expect("exports");
        assert!(
            report.camera && report.lights == doc.lights.len(),
            "{report:?}"
        );
        let import =
            crate::io::import_gltf_imported(&path, &ImportLimits::default()).expect("imports");
        let mut back = Document::default();
        back.add(
            "block",
            ObjectKind::Mesh(MeshObject {
                model: import.model,
                casts_shadows: true,
            }),
        );
        import.view.apply_to_new_document(&mut back);
        back.validate().expect("a valid document");
        (back, import.report)
    }

    fn close(a: f32, b: f32, tolerance: f32) -> bool {
        (a - b).abs() <= tolerance * (1.0 + a.abs().max(b.abs()))
    }

    fn assert_lights_round_trip(doc: &Document, back: &Document) {
        assert_eq!(back.lights.len(), doc.lights.len(), "{:?}", back.lights);
        for (a, b) in doc.lights.iter().zip(&back.lights) {
            assert_eq!(a.name, b.name);
            assert!(
                a.direction.normalize_or_zero().dot(b.direction) > 1.0 - 1e-5,
                "{a:?} {b:?}"
            );
            assert!(a.color.abs_diff_eq(b.color, 1e-6), "{a:?} {b:?}");
            assert!(close(a.intensity, b.intensity, 1e-6), "{a:?} {b:?}");
            // The strongest casts shadows: here the sun, as in the document.
            assert_eq!(a.casts_shadows, b.casts_shadows, "{a:?} {b:?}");
        }
    }

    #[test]
    fn an_exported_view_imports_as_the_same_camera_and_lights() {
        let doc = lit_document(-140.0, 28.0, 50.0);
        let (back, report) = round_trip(&doc);
        let (a, b) = (doc.camera, back.camera);
        assert!(!b.orthographic);
        assert!(close(a.yaw_deg, b.yaw_deg, 1e-4), "{a:?} {b:?}");
        assert!(close(a.pitch_deg, b.pitch_deg, 1e-4), "{a:?} {b:?}");
        assert!(close(a.fov_y_deg, b.fov_y_deg, 1e-5), "{a:?} {b:?}");
        // The camera was framed on the model: its target is the model's centre again.
        assert!(close(a.distance, b.distance, 1e-4), "{a:?} {b:?}");
        assert!(a.target.abs_diff_eq(b.target, 1e-4), "{a:?} {b:?}");
        assert!(a.eye().abs_diff_eq(b.eye(), 1e-4), "{a:?} {b:?}");
        assert!(
            close(a.near, b.near, 1e-5) && close(a.far, b.far, 1e-5),
            "{a:?} {b:?}"
        );
        assert_lights_round_trip(&doc, &back);
        // Said once each; no roll on a camera the exporter wrote.
        let count = |s: &str| report.iter().filter(|l| l.contains(s)).count();
        assert_eq!(
            count("1 camera(s): the first imported as the document camera"),
            1,
            "{report:?}"
        );
        assert_eq!(
            count("lights: 2 directional imported, 0 point/spot not imported"),
            1,
            "{report:?}"
        );
        assert_eq!(count("roll"), 0, "{report:?}");
        assert_eq!(report.len(), 2, "{report:?}");
    }

    #[test]
    fn an_exported_orthographic_view_imports_as_the_same_parallel_view() {
        let mut doc = lit_document(35.0, 60.0, 45.0);
        doc.camera.orthographic = true;
        // A near plane behind the eye: the exporter pulls its node back along the view axis.
        doc.camera.near = -2.0;
        doc.camera.far = 7.0;
        let (back, _) = round_trip(&doc);
        let (a, b) = (doc.camera, back.camera);
        assert!(b.orthographic);
        assert!(close(a.yaw_deg, b.yaw_deg, 1e-4), "{a:?} {b:?}");
        assert!(close(a.pitch_deg, b.pitch_deg, 1e-4), "{a:?} {b:?}");
        assert!(
            close(a.ortho_half_height(), b.ortho_half_height(), 1e-5),
            "{a:?} {b:?}"
        );
        // The same view axis, and the same near and far planes in the world.
        let forward = (a.target - a.eye()).normalize_or_zero();
        let off_axis = (b.target - a.target).reject_from(forward);
        assert!(off_axis.length() < 1e-4, "{off_axis}");
        let plane = |c: &OrbitCamera, depth: f32| (c.eye() + forward * depth).dot(forward);
        assert!(
            close(plane(&a, a.near), plane(&b, b.near), 1e-4),
            "{a:?} {b:?}"
        );
        assert!(
            close(plane(&a, a.far), plane(&b, b.far), 1e-4),
            "{a:?} {b:?}"
        );
        assert_lights_round_trip(&doc, &back);
    }

    /// `root`'s default scene nodes with their world transforms (parents before children).
    fn world_transforms(root: &json::Root) -> Vec<(usize, Mat4)> {
        fn visit(root: &json::Root, n: usize, parent: Mat4, out: &mut Vec<(usize, Mat4)>) {
            let node = &root.nodes[n];
            let local = Mat4::from_scale_rotation_translation(
                Vec3::from_array(node.scale.unwrap_or([1.0; 3])),
                Quat::from_array(node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)),
                Vec3::from_array(node.translation.unwrap_or([0.0; 3])),
            );
            out.push((n, parent * local));
            for c in node.children.iter().flatten() {
                visit(root, c.value(), parent * local, out);
            }
        }
        let mut out = Vec::new();
        for n in &root.scenes[0].nodes {
            visit(root, n.value(), Mat4::IDENTITY, &mut out);
        }
        out
    }

    #[test]
    fn lights_in_a_hierarchy_and_a_rolled_camera_are_read_and_reported() {
        let roll = Quat::from_rotation_z(0.5);
        let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let root: json::Root = serde_json::from_value(serde_json::json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0, 3]}],
            "nodes": [
                {"rotation": turn.to_array(), "children": [1, 2]},
                {"name": "key", "extensions": {"KHR_lights_punctual": {"light": 0}}},
                {"extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"camera": 1, "translation": [0.0, 1.0, 5.0], "rotation": roll.to_array(),
                 "children": [4]},
                {"camera": 0},
                {"extensions": {"KHR_lights_punctual": {"light": 2}}}
            ],
            "cameras": [
                {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}},
                {"name": "Shot", "type": "perspective",
                 "perspective": {"yfov": 0.9, "znear": 0.2, "zfar": 50.0}}
            ],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "directional", "color": [1.0, 0.5, 0.25], "intensity": 3.0},
                {"type": "point", "intensity": 10.0},
                {"type": "spot", "spot": {}},
                {"type": "directional", "name": "orphan"}
            ]}},
            "extensionsUsed": ["KHR_lights_punctual"]
        }))
        .unwrap();
        let (view, lines) = read_view(&root, &world_transforms(&root));
        // The directional light under a node turned a quarter about +Y shines along −X.
        let [key] = &view.lights[..] else {
            panic!("one directional light: {:?}", view.lights);
        };
        assert!(key.direction.abs_diff_eq(Vec3::NEG_X, 1e-6), "{key:?}");
        assert_eq!(key.name, "key");
        assert_eq!((key.color, key.intensity), (Vec3::new(1.0, 0.5, 0.25), 3.0));
        assert!(key.casts_shadows);
        // The first camera in the scene's order is node 3's ("Shot"), not camera 0.
        let camera = view.camera.unwrap();
        assert!(close(camera.fov_y_deg, 0.9f32.to_degrees(), 1e-6));
        assert_eq!((camera.znear, camera.zfar), (0.2, Some(50.0)));
        let orbit = camera.orbit_camera(Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
        assert!(
            orbit.eye().abs_diff_eq(Vec3::new(0.0, 1.0, 5.0), 1e-5),
            "{orbit:?}"
        );
        assert!(close(orbit.distance, 5.0, 1e-6) && orbit.yaw_deg.abs() < 1e-4);
        assert_eq!(
            lines,
            [
                "2 camera(s): the first imported as the document camera (\"Shot\")",
                "camera \"Shot\": its roll of 28.6° is dropped (the document camera keeps the \
                 world's +Y up)",
                "lights: 1 directional imported, 2 point/spot not imported (Thicket lights are \
                 directional); 1 directional not placed by any node of the scene",
            ]
        );
    }

    #[test]
    fn file_import_adds_lights_without_a_second_shadow_caster() {
        let view = GltfView {
            camera: None,
            lights: vec![Light::default()],
        };
        let mut doc = Document::default();
        let camera = doc.camera;
        view.add_lights_to(&mut doc);
        assert_eq!(doc.lights.len(), 2);
        assert!(doc.lights[0].casts_shadows && !doc.lights[1].casts_shadows);
        assert_eq!(doc.camera, camera);
        // A new document takes the file's lights instead of its default sun.
        let mut new = Document::default();
        view.apply_to_new_document(&mut new);
        assert_eq!(new.lights, view.lights);
    }
}
