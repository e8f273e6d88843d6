//! Tests of the preview renderer.

use super::camera::*;
use super::raster::*;
use std::path::Path;

use super::*;

/// A square of side `size` in the plane z = `z`, centred on the z axis, facing +z.
fn square(size: f64, z: f64) -> Mesh {
    let s = 0.5 * size;
    Mesh {
        positions: vec![[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

fn front_camera(distance: f64) -> Camera {
    Camera {
        eye: [0.0, 0.0, distance],
        target: [0.0; 3],
        up: [0.0, 1.0, 0.0],
        fov_y_degrees: 60.0,
    }
}

/// Number of pixels that differ from the background.
fn covered(image: &Image) -> usize {
    (0..image.height)
        .flat_map(|y| (0..image.width).map(move |x| (x, y)))
        .filter(|&(x, y)| image.pixel(x, y) != Some(background(y, image.height)))
        .count()
}

fn is_background(image: &Image) -> bool {
    covered(image) == 0
}

#[test]
fn unit_quad_covers_expected_fraction() {
    let quad = square(1.0, 0.0);
    let color = [200, 100, 50];
    let image = render(
        &[PreviewItem::Mesh(&quad, color)],
        &front_camera(2.0),
        200,
        200,
    );
    assert_eq!(
        (image.width, image.height, image.rgb.len()),
        (200, 200, 120_000)
    );
    // Focal length 100 / tan(30°) px; the quad spans focal * 1 / 2 px.
    let side = 100.0 / 30f64.to_radians().tan() * 0.5;
    let expected = side * side;
    let count = covered(&image) as f64;
    assert!(
        (count - expected).abs() < 0.03 * expected,
        "covered {count}, expected {expected}"
    );
    // Centre: flat Lambert with |n·l| = 0.6 / |(-0.5, 0.6, 0.6)|.
    let intensity = 0.2 + 0.8 * 0.6 / (0.25_f64 + 0.36 + 0.36).sqrt();
    let shaded = color.map(|c| (f64::from(c) * intensity).round() as u8);
    assert_eq!(image.pixel(100, 100), Some(shaded));
    assert_eq!(image.pixel(60, 60), Some(shaded));
    // Corners and outside the quad: background.
    assert_eq!(image.pixel(0, 0), Some(background(0, 200)));
    assert_eq!(image.pixel(199, 199), Some(background(199, 200)));
    assert_eq!(image.pixel(100, 20), Some(background(20, 200)));
    // Seen from behind it looks the same (two-sided).
    let back = render(
        &[PreviewItem::Mesh(&quad, color)],
        &Camera {
            eye: [0.0, 0.0, -2.0],
            ..front_camera(2.0)
        },
        200,
        200,
    );
    assert_eq!(covered(&back), covered(&image));
}

#[test]
fn z_buffer_keeps_the_nearest_surface() {
    let near = square(1.0, 0.5);
    let far = square(2.0, 0.0);
    let (red, blue) = ([255, 0, 0], [0, 0, 255]);
    for items in [
        [PreviewItem::Mesh(&near, red), PreviewItem::Mesh(&far, blue)],
        [PreviewItem::Mesh(&far, blue), PreviewItem::Mesh(&near, red)],
    ] {
        let image = render(&items, &front_camera(3.0), 100, 100);
        let centre = image.pixel(50, 50).expect("pixel");
        assert!(centre[0] > 0 && centre[2] == 0, "{centre:?}");
        // 25 px from the centre only the far square is visible (half-sizes 17 and 29 px).
        let edge = image.pixel(50, 25).expect("pixel");
        assert!(edge[0] == 0 && edge[2] > 0, "{edge:?}");
    }
}

#[test]
fn empty_and_degenerate_scenes_are_background() {
    let camera = front_camera(2.0);
    assert!(is_background(&render(&[], &camera, 64, 48)));
    let empty = Mesh::default();
    let no_curves = Curves::default();
    let flat = Mesh {
        positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        triangles: vec![[0, 1, 2], [0, 0, 0]],
    };
    let bad_index = Mesh {
        positions: vec![[0.0; 3]],
        triangles: vec![[0, 5, 9]],
    };
    let bad_offsets = Curves {
        positions: vec![[0.0; 3], [1.0, 0.0, 0.0]],
        offsets: vec![0, 5],
    };
    let items = [
        PreviewItem::Mesh(&empty, [0; 3]),
        PreviewItem::Curves(&no_curves, [0; 3]),
        PreviewItem::Mesh(&flat, [0; 3]),
        PreviewItem::Mesh(&bad_index, [0; 3]),
        PreviewItem::Curves(&bad_offsets, [0; 3]),
    ];
    assert!(is_background(&render(&items, &camera, 64, 48)));
    // Zero-sized images and unusable cameras.
    assert_eq!(render(&items, &camera, 0, 10).rgb.len(), 0);
    let quad = square(1.0, 0.0);
    let one = [PreviewItem::Mesh(&quad, [0; 3])];
    for cam in [
        Camera {
            eye: [0.0; 3],
            ..camera
        },
        Camera {
            eye: [f64::NAN; 3],
            ..camera
        },
        Camera {
            up: [0.0, 0.0, 1.0],
            fov_y_degrees: f64::NAN,
            ..camera
        },
    ] {
        let image = render(&one, &cam, 32, 32);
        assert_eq!(image.rgb.len(), 32 * 32 * 3);
    }
}

#[test]
fn nan_vertices_and_geometry_behind_the_camera_do_not_panic() {
    let mut quad = square(1.0, 0.0);
    quad.positions[1] = [f64::NAN, 0.0, f64::INFINITY];
    let curves = Curves {
        positions: vec![[f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0], [0.1, 0.1, 0.0]],
        offsets: vec![0, 3],
    };
    let items = [
        PreviewItem::Mesh(&quad, [255; 3]),
        PreviewItem::Curves(&curves, [0; 3]),
    ];
    let image = render(&items, &front_camera(2.0), 64, 64);
    // The triangle without the NaN vertex and the finite segment are drawn.
    assert!(covered(&image) > 100);

    // Entirely behind the camera: nothing.
    let behind = square(1.0, 5.0);
    let strand = Curves {
        positions: vec![[0.0, 0.0, 4.0], [0.0, 0.0, 6.0]],
        offsets: vec![0, 2],
    };
    let items = [
        PreviewItem::Mesh(&behind, [255; 3]),
        PreviewItem::Curves(&strand, [0; 3]),
    ];
    assert!(is_background(&render(&items, &front_camera(2.0), 64, 64)));

    // Through the camera plane: clipped, drawn in front, no panic.
    let big = square(100.0, 0.0);
    let through = Mesh {
        positions: vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, -1.0, 10.0]],
        triangles: vec![[0, 1, 2]],
    };
    let long = Curves {
        positions: vec![[0.2, 0.1, -3.0], [0.2, 0.1, 1e9]],
        offsets: vec![0, 2],
    };
    let items = [
        PreviewItem::Mesh(&big, [255; 3]),
        PreviewItem::Mesh(&through, [0, 255, 0]),
        PreviewItem::Curves(&long, [0; 3]),
    ];
    let image = render(&items, &front_camera(2.0), 64, 64);
    assert_eq!(covered(&image), 64 * 64);
}

#[test]
fn curves_draw_depth_tested_lines() {
    // A horizontal strand 1 m in front of the origin, spanning the view.
    let strand = Curves {
        positions: vec![[-10.0, 0.0, 1.0], [0.0, 0.0, 1.0], [10.0, 0.0, 1.0]],
        offsets: vec![0, 3],
    };
    let image = render(
        &[PreviewItem::Curves(&strand, [0, 0, 0])],
        &front_camera(2.0),
        120,
        80,
    );
    // One pixel per column, all on the middle rows.
    let count = covered(&image);
    assert_eq!(count, 120);
    let row = (0..80)
        .find(|&y| image.pixel(60, y) != Some(background(y, 80)))
        .expect("line");
    assert!((39..=40).contains(&row), "{row}");
    // Hidden behind a surface nearer to the eye.
    let wall = square(50.0, 1.5);
    let hidden = render(
        &[
            PreviewItem::Mesh(&wall, [255; 3]),
            PreviewItem::Curves(&strand, [0; 3]),
        ],
        &front_camera(2.0),
        120,
        80,
    );
    let wall_only = render(
        &[PreviewItem::Mesh(&wall, [255; 3])],
        &front_camera(2.0),
        120,
        80,
    );
    assert!(hidden.rgb == wall_only.rgb);
    // A line lying on a surface shows.
    let on = square(50.0, 1.0);
    let image = render(
        &[
            PreviewItem::Mesh(&on, [255; 3]),
            PreviewItem::Curves(&strand, [0; 3]),
        ],
        &front_camera(2.0),
        120,
        80,
    );
    let dark = image.rgb.chunks(3).filter(|p| p[0] < 10).count();
    assert_eq!(dark, 120);
    // A strand of many sub-pixel segments is drawn without gaps: a diagonal of 1000
    // segments across the image covers one pixel per column.
    let fine = Curves {
        positions: (0..=1000)
            .map(|k| {
                let s = k as f64 / 1000.0;
                [-0.9 + 1.8 * s, -0.3 + 0.6 * s, 1.0]
            })
            .collect(),
        offsets: vec![0, 1001],
    };
    let image = render(
        &[PreviewItem::Curves(&fine, [0; 3])],
        &front_camera(2.0),
        120,
        80,
    );
    for x in 0..120 {
        let n = (0..80)
            .filter(|&y| image.pixel(x, y) != Some(background(y, 80)))
            .count();
        assert_eq!(n, 1, "column {x}");
    }
}

#[test]
fn auto_camera_frames_the_bounds() {
    let bounds = ([-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]);
    let cam = auto_camera(bounds, 1.5);
    assert_eq!(cam, auto_camera(bounds, 1.5));
    assert_eq!(cam.target, [0.0, 1.0, 0.0]);
    let d = sub(cam.eye, cam.target);
    assert!(
        d[0] > 0.0 && d[1] > 0.0 && d[2] > d[0] && d[2] > d[1],
        "{d:?}"
    );
    // Bounding-sphere radius sqrt(3) fits the 35° vertical field with a 15 % margin.
    let distance = norm(d);
    let expected = 1.15 * 3f64.sqrt() / 17.5f64.to_radians().sin();
    assert!(
        (distance - expected).abs() < 1e-12,
        "{distance} vs {expected}"
    );
    // Every corner of the box projects inside the image.
    let view = View::new(&cam, 300, 200).expect("view");
    for k in 0..8 {
        let corner = [0, 1, 2].map(|a| {
            if k >> a & 1 == 1 {
                bounds.1[a]
            } else {
                bounds.0[a]
            }
        });
        let s = view.project(view.to_camera(corner));
        assert!(
            (0.0..300.0).contains(&s[0]) && (0.0..200.0).contains(&s[1]),
            "{s:?}"
        );
    }
    // Degenerate input gets a default 1 m extent.
    let point = auto_camera(([1.0; 3], [1.0; 3]), f64::NAN);
    let expected = 1.15 * 0.5 / 17.5f64.to_radians().sin();
    assert!((norm(sub(point.eye, point.target)) - expected).abs() < 1e-12);
    let nan = auto_camera(([f64::NAN; 3], [f64::INFINITY; 3]), 0.0);
    assert!(finite(nan.eye) && nan.target == [0.0; 3]);
}

#[test]
fn scene_bounds_skip_non_finite_points() {
    let mut quad = square(2.0, 0.5);
    quad.positions.push([f64::NAN, 100.0, 0.0]);
    let strand = Curves {
        positions: vec![[0.0, 3.0, 0.0], [f64::INFINITY, 0.0, 0.0]],
        offsets: vec![0, 2],
    };
    let items = [
        PreviewItem::Mesh(&quad, [0; 3]),
        PreviewItem::Curves(&strand, [0; 3]),
    ];
    assert_eq!(
        scene_bounds(&items),
        Some(([-1.0, -1.0, 0.0], [1.0, 3.0, 0.5]))
    );
    assert_eq!(scene_bounds(&[]), None);
}

#[test]
fn dense_grid_has_no_holes() {
    // A unit square as 128 x 128 quads = 32768 triangles covers the same pixels as the
    // same square made of two triangles: shared edges leave no gaps.
    let n = 129;
    let mut grid = Mesh::default();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f64 / 128.0 - 0.5, j as f64 / 128.0 - 0.5);
            grid.positions.push([x, y, 0.0]);
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = (j * n + i) as u32;
            let n = n as u32;
            grid.triangles.push([v, v + 1, v + n + 1]);
            grid.triangles.push([v, v + n + 1, v + n]);
        }
    }
    assert_eq!(grid.triangles.len(), 32768);
    let camera = front_camera(2.0);
    let start = std::time::Instant::now();
    let image = render(&[PreviewItem::Mesh(&grid, [180; 3])], &camera, 512, 512);
    let elapsed = start.elapsed();
    let reference = render(
        &[PreviewItem::Mesh(&square(1.0, 0.0), [180; 3])],
        &camera,
        512,
        512,
    );
    let differing = image
        .rgb
        .iter()
        .zip(&reference.rgb)
        .filter(|(p, q)| p != q)
        .count();
    assert_eq!(differing, 0, "render took {elapsed:?}");
    // Half-size focal / 4 = 110.9 px: about 221.7^2 pixels.
    let count = covered(&image) as f64;
    assert!((count - 49_152.0).abs() < 0.02 * 49_152.0, "{count}");
}

#[test]
fn png_has_signature_and_header() {
    let dir = tempfile::tempdir().expect("dir");
    let path = dir.path().join("preview.png");
    let quad = square(1.0, 0.0);
    let image = render(
        &[PreviewItem::Mesh(&quad, [10, 200, 30])],
        &front_camera(2.0),
        37,
        21,
    );
    write_png(&image, &path).expect("write");
    let bytes = std::fs::read(&path).expect("read");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&bytes[8..16], b"\0\0\0\x0dIHDR");
    assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().expect("4")), 37);
    assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().expect("4")), 21);
    assert_eq!((bytes[24], bytes[25]), (8, 2)); // 8-bit RGB
    // Pixels survive, and no temporary file is left behind.
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("info");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("frame");
    assert_eq!(&buf[..info.buffer_size()], &image.rgb[..]);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(names, ["preview.png"]);

    // Overwrites atomically; bad images and paths are errors.
    write_png(&image, &path).expect("overwrite");
    let empty = Image {
        width: 0,
        height: 5,
        rgb: vec![],
    };
    assert!(matches!(
        write_png(&empty, &path),
        Err(PreviewError::Invalid { .. })
    ));
    let short = Image {
        width: 2,
        height: 2,
        rgb: vec![0; 5],
    };
    assert!(write_png(&short, &path).is_err());
    let missing = dir.path().join("no/such/dir/x.png");
    let err = write_png(&image, &missing).expect_err("missing dir");
    assert!(matches!(err, PreviewError::Io { .. }), "{err}");
    assert!(write_png(&image, Path::new("/")).is_err());
}
