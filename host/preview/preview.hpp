// Pictures of a scan mesh with the project's own ray caster (host/raycast, Embree): the
// thumbnail facescand writes beside each scan, and the reference silhouette the viewer's browser
// test compares against. The framing is the web viewer's (host/viewer/page/viewer.js frames the
// same way), so a picture here and a screenshot there show the same view.
#pragma once

#include "common/status.hpp"
#include "recon/types.hpp"

#include <opencv2/core.hpp>

namespace facescan::preview {

/// A pinhole looking at `target` from `eye` with world +y up; vertical field of view in degrees.
struct Camera {
	cv::Vec3d eye, target;
	double fov_y_deg = 30;
	int width = 0, height = 0;
};

/// The viewer's framing: looks at the centre of the mesh's bounding box from azimuth_deg about
/// +y (0 = from +z, the face's front; positive towards +x), from the distance at which the
/// bounding sphere (half the box diagonal) just fills the vertical field of view.
Camera frame_mesh(const recon::Mesh &mesh, double azimuth_deg, int width, int height, double fov_y_deg = 30);

/// Renders the mesh: its texture (else vertex colours, else grey) lit by a headlight, on a dark
/// background. ret_mask (optional): CV_8U, 255 where a ray hit the mesh. -EINVAL for an empty
/// mesh or a camera without pixels; -ENOMEM / -EIO when Embree fails.
Status render(const recon::Mesh &mesh, const Camera &camera, cv::Mat *ret_bgr, cv::Mat *ret_mask);

/// The scan's thumbnail: three views side by side, from -45°, the front and +45°, each
/// view_width x view_height.
Status thumbnail(const recon::Mesh &mesh, int view_width, int view_height, cv::Mat *ret_bgr);

} // namespace facescan::preview
