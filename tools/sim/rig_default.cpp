// The built-in default rig: the text of tools/sim/rigs/default.yaml, verbatim (a test compares).
namespace facescan::sim {
extern const char *const kDefaultRigYaml;
const char *const kDefaultRigYaml = R"yaml(%YAML:1.0
---
# facescan booth rig: the default of `facescan simulate` (built into the binary as
# facescan::sim::default_rig(); tests/sim checks that this file and the built-in rig agree).
# Units: mm, degrees, pixels. World: head near the origin, +y up, +z out of the face.
# Devices are placed at azimuth (about +y; 0 = in front on +z, positive towards +x),
# elevation (up) and distance from their target point, looking at it with +y up.
# Every key is documented in docs/simulator.md.
# The projectors are rolled 90 degrees (portrait): each 4:3 slide then covers a tall strip of
# the face (about 120 mm wide x 160 mm high) and the three strips tile the face from ear to ear
# with ~95 % coverage and ~11-18 % overlap at the seams. Upright (landscape) slides cannot cover
# the face's height without overlapping most of it (rigs/landscape.yaml: ~73 % coverage).
# In the camera images the slide's "up" therefore points to the image right.
supersample: 1
cameras:
  - { name: cam0, azimuth_deg: -60.0, elevation_deg: 0.0, distance_mm: 550.0,
      target_mm: [ 0.0, -10.0, 40.0 ], roll_deg: 0.0, size: [ 1600, 1200 ],
      focal_px: [ 2000.0, 2000.0 ], principal_px: [ 803.5, 597.0 ],
      dist: [ -0.060, 0.090, 0.0004, -0.0003, 0.0 ],
      focus_mm: 550.0, blur_px: 0.5, defocus_px_per_100mm: 0.8, exposure: 1.0 }
  - { name: cam1, azimuth_deg: -20.0, elevation_deg: 0.0, distance_mm: 550.0,
      target_mm: [ 0.0, -10.0, 40.0 ], roll_deg: 0.0, size: [ 1600, 1200 ],
      focal_px: [ 2004.0, 2003.0 ], principal_px: [ 797.0, 602.5 ],
      dist: [ -0.055, 0.080, -0.0002, 0.0005, 0.0 ],
      focus_mm: 550.0, blur_px: 0.5, defocus_px_per_100mm: 0.8, exposure: 1.0 }
  - { name: cam2, azimuth_deg: 20.0, elevation_deg: 0.0, distance_mm: 550.0,
      target_mm: [ 0.0, -10.0, 40.0 ], roll_deg: 0.0, size: [ 1600, 1200 ],
      focal_px: [ 1997.0, 1998.0 ], principal_px: [ 801.0, 598.5 ],
      dist: [ -0.062, 0.095, 0.0003, 0.0002, 0.0 ],
      focus_mm: 550.0, blur_px: 0.5, defocus_px_per_100mm: 0.8, exposure: 1.0 }
  - { name: cam3, azimuth_deg: 60.0, elevation_deg: 0.0, distance_mm: 550.0,
      target_mm: [ 0.0, -10.0, 40.0 ], roll_deg: 0.0, size: [ 1600, 1200 ],
      focal_px: [ 2001.0, 2001.5 ], principal_px: [ 798.5, 601.0 ],
      dist: [ -0.058, 0.085, -0.0004, -0.0001, 0.0 ],
      focus_mm: 550.0, blur_px: 0.5, defocus_px_per_100mm: 0.8, exposure: 1.0 }
projectors:
  - { name: proj0, azimuth_deg: -45.0, elevation_deg: 12.0, distance_mm: 600.0,
      target_mm: [ -90.0, -25.0, 20.0 ], roll_deg: 90.0, size: [ 1024, 768 ],
      focal_px: [ 3614.0, 3614.0 ], power: 1.6, focus_mm: 600.0, blur_px: 0.6,
      defocus_px_per_100mm: 1.5, gamma: 2.2 }
  - { name: proj1, azimuth_deg: 0.0, elevation_deg: 12.0, distance_mm: 600.0,
      target_mm: [ 0.0, -25.0, 60.0 ], roll_deg: 90.0, size: [ 1024, 768 ],
      focal_px: [ 3840.0, 3840.0 ], power: 1.6, focus_mm: 600.0, blur_px: 0.6,
      defocus_px_per_100mm: 1.5, gamma: 2.2 }
  - { name: proj2, azimuth_deg: 45.0, elevation_deg: 12.0, distance_mm: 600.0,
      target_mm: [ 90.0, -25.0, 20.0 ], roll_deg: 90.0, size: [ 1024, 768 ],
      focal_px: [ 3614.0, 3614.0 ], power: 1.6, focus_mm: 600.0, blur_px: 0.6,
      defocus_px_per_100mm: 1.5, gamma: 2.2 }
sensor:
  full_well_e: 9000.0
  read_noise_e: 6.0
  adc_bits: 12
  gamma: 2.2
  crosstalk: [ 0.86, 0.11, 0.03,
               0.08, 0.84, 0.08,
               0.03, 0.12, 0.85 ]
  bayer: 1
  noise_scale: 1.0
lighting:
  ambient_pattern: 0.03
  ambient_texture: 0.12
  lights:
    - { azimuth_deg: -35.0, elevation_deg: 20.0, intensity: 0.45 }
    - { azimuth_deg: 35.0, elevation_deg: 20.0, intensity: 0.45 }
    - { azimuth_deg: 0.0, elevation_deg: 60.0, intensity: 0.2 }
)yaml";
} // namespace facescan::sim
