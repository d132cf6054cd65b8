//! Cameras for the CPU renderers: a view transform plus a perspective or orthographic
//! projection onto a pixel grid.
//!
//! Screen space: pixel `(i, j)` spans `[i, i+1) × [j, j+1)`, row 0 at the top, pixel centres at
//! `+0.5`. View space is right-handed, looking down −Z; *view depth* `d = −z_view` is positive in
//! front of the eye. Stored depth is **NDC z in 0..1** (wgpu convention: 0 at the near plane,
//! 1 at the far plane), exactly what `clip_from_world` produces, so a GPU renderer's hardware
//! depth buffer holds the same numbers.

use glam::{Mat3, Mat4, Vec3, Vec4};

use crate::scene::OrbitCamera;

/// How view space maps to the image plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Pinhole camera (the view camera).
    Perspective {
        /// Vertical field of view in radians.
        fov_y_rad: f32,
        /// Near plane view depth (> 0).
        near: f32,
        /// Far plane view depth.
        far: f32,
    },
    /// Parallel projection (the directional light's shadow camera, orthographic views).
    Orthographic {
        /// Half the view-space width that maps onto the image.
        half_width: f32,
        /// Half the view-space height that maps onto the image.
        half_height: f32,
        /// Near plane view depth (may be negative for orthographic).
        near: f32,
        /// Far plane view depth.
        far: f32,
    },
}

impl Projection {
    /// An orbit camera's projection for an aspect ratio (width / height). (Here, not on
    /// [`OrbitCamera`], so the document does not depend on a renderer type.)
    #[must_use]
    pub fn of_orbit(orbit: &OrbitCamera, aspect: f32) -> Self {
        if orbit.orthographic {
            let half_height = orbit.ortho_half_height();
            Self::Orthographic {
                half_width: half_height * aspect,
                half_height,
                near: orbit.near,
                far: orbit.far,
            }
        } else {
            Self::Perspective {
                fov_y_rad: orbit.fov_y_deg.to_radians(),
                near: orbit.near,
                far: orbit.far,
            }
        }
    }
}

/// A camera with an image size: everything needed to project a point to a pixel and a depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// `view_from_world` (rigid).
    pub view_from_world: Mat4,
    /// The projection.
    pub projection: Projection,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Pixels per view-space unit at view depth 1 (perspective) or per unit (orthographic), x.
    pub(crate) fx: f32,
    /// Same for y.
    pub(crate) fy: f32,
    pub(crate) near: f32,
    pub(crate) far: f32,
    pub(crate) perspective: bool,
    pub(crate) world_from_view: Mat4,
}

impl Camera {
    /// The document's orbit camera at an image size (aspect = width / height).
    #[must_use]
    pub fn from_orbit(orbit: &OrbitCamera, width: u32, height: u32) -> Self {
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        Self::new(
            orbit.view_from_world(),
            Projection::of_orbit(orbit, aspect),
            width,
            height,
        )
    }

    /// A camera from an explicit view transform and projection.
    #[must_use]
    pub fn new(view_from_world: Mat4, projection: Projection, width: u32, height: u32) -> Self {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let (fx, fy, near, far, perspective) = match projection {
            Projection::Perspective {
                fov_y_rad,
                near,
                far,
            } => {
                let fy = 0.5 * h / (0.5 * fov_y_rad).tan();
                (fy, fy, near, far, true)
            }
            Projection::Orthographic {
                half_width,
                half_height,
                near,
                far,
            } => (
                0.5 * w / half_width,
                0.5 * h / half_height,
                near,
                far,
                false,
            ),
        };
        Self {
            view_from_world,
            projection,
            width,
            height,
            fx,
            fy,
            near,
            far,
            perspective,
            world_from_view: view_from_world.inverse(),
        }
    }

    /// `clip_from_view` with depth 0..1 (the matrix a GPU renderer uses for the same image).
    #[must_use]
    pub fn clip_from_view(&self) -> Mat4 {
        match self.projection {
            Projection::Perspective {
                fov_y_rad,
                near,
                far,
            } => Mat4::perspective_rh(
                fov_y_rad,
                self.width.max(1) as f32 / self.height.max(1) as f32,
                near,
                far,
            ),
            Projection::Orthographic {
                half_width,
                half_height,
                near,
                far,
            } => Mat4::orthographic_rh(
                -half_width,
                half_width,
                -half_height,
                half_height,
                near,
                far,
            ),
        }
    }

    /// `clip_from_world`.
    #[must_use]
    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_view() * self.view_from_world
    }

    /// Eye position in world space (for orthographic cameras: the view origin).
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.world_from_view.w_axis.truncate()
    }

    /// Near plane view depth.
    #[must_use]
    pub fn near(&self) -> f32 {
        self.near
    }

    /// Far plane view depth.
    #[must_use]
    pub fn far(&self) -> f32 {
        self.far
    }

    /// Pixels per view-space unit (x, y): at view depth 1 for perspective, everywhere for
    /// orthographic.
    #[must_use]
    pub fn focal_px(&self) -> (f32, f32) {
        (self.fx, self.fy)
    }

    /// Whether the projection is perspective (otherwise orthographic).
    #[must_use]
    pub fn is_perspective(&self) -> bool {
        self.perspective
    }

    /// The rotation part of `view_from_world`.
    pub(crate) fn view_rotation(&self) -> Mat3 {
        Mat3::from_mat4(self.view_from_world)
    }

    /// NDC depth (0 at near, 1 at far) of a view depth.
    #[inline]
    #[must_use]
    pub fn ndc_depth(&self, view_depth: f32) -> f32 {
        if self.perspective {
            self.far / (self.far - self.near) * (1.0 - self.near / view_depth)
        } else {
            (view_depth - self.near) / (self.far - self.near)
        }
    }

    /// Inverse of [`Camera::ndc_depth`].
    #[inline]
    #[must_use]
    pub fn view_depth(&self, ndc_depth: f32) -> f32 {
        if self.perspective {
            self.near / (1.0 - ndc_depth * (self.far - self.near) / self.far)
        } else {
            self.near + ndc_depth * (self.far - self.near)
        }
    }

    /// Projects a view-space point: `(screen x, screen y, view depth)`. Perspective points at
    /// or behind the eye give non-finite screen coordinates; callers clip first.
    #[inline]
    #[must_use]
    pub fn project_view(&self, p_view: Vec3) -> Vec3 {
        let d = -p_view.z;
        let (sx, sy) = if self.perspective {
            (p_view.x / d, p_view.y / d)
        } else {
            (p_view.x, p_view.y)
        };
        Vec3::new(
            0.5 * self.width as f32 + self.fx * sx,
            0.5 * self.height as f32 - self.fy * sy,
            d,
        )
    }

    /// World position of a screen point (pixel units) at an NDC depth.
    #[must_use]
    pub fn unproject(&self, screen_x: f32, screen_y: f32, ndc_depth: f32) -> Vec3 {
        let d = self.view_depth(ndc_depth);
        let sx = (screen_x - 0.5 * self.width as f32) / self.fx;
        let sy = (0.5 * self.height as f32 - screen_y) / self.fy;
        let p_view = if self.perspective {
            Vec3::new(sx * d, sy * d, -d)
        } else {
            Vec3::new(sx, sy, -d)
        };
        self.world_from_view.transform_point3(p_view)
    }

    /// Unit direction from a world point towards the eye (the view axis's back direction
    /// for an orthographic camera, whose rays are parallel).
    #[inline]
    #[must_use]
    pub fn toward_eye(&self, p_world: Vec3) -> Vec3 {
        if self.perspective {
            (self.eye() - p_world).normalize_or_zero()
        } else {
            self.world_from_view.z_axis.truncate().normalize_or_zero()
        }
    }

    /// World-space size of one pixel at a view depth (the footprint used for biases).
    #[must_use]
    pub fn pixel_world_size(&self, view_depth: f32) -> f32 {
        if self.perspective {
            view_depth.abs() / self.fy
        } else {
            1.0 / self.fy.min(self.fx)
        }
    }

    /// Screen position and NDC depth of a world point, via `clip_from_world` (tests use this to
    /// check the fast paths against the matrix a GPU would use).
    #[must_use]
    pub fn world_to_screen(&self, p_world: Vec3) -> Vec3 {
        let clip = self.clip_from_world() * Vec4::from((p_world, 1.0));
        let ndc = clip.truncate() / clip.w;
        Vec3::new(
            (ndc.x * 0.5 + 0.5) * self.width as f32,
            (0.5 - ndc.y * 0.5) * self.height as f32,
            ndc.z,
        )
    }
}
