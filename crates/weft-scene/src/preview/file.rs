//! PNG output of an [`Image`].

use super::{Image, PreviewError};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `image` as an 8-bit RGB PNG at `path`, atomically: the data goes to
/// `<path>.png.tmp`-style sibling file (`path.with_extension("png.tmp")`), which is synced and
/// then renamed over `path`, so readers never see a partial file.
///
/// # Errors
///
/// [`PreviewError::Invalid`] for a zero-sized image, pixel data whose length is not
/// `width * height * 3`, or a path without a file name; [`PreviewError::Io`] and
/// [`PreviewError::Png`] when writing fails (the temporary file is then removed).
pub fn write_png(image: &Image, path: &Path) -> Result<(), PreviewError> {
    if path.file_name().is_none() {
        return Err(PreviewError::Invalid {
            path: path.to_owned(),
            message: "the path does not name a file".into(),
        });
    }
    let tmp = path.with_extension("png.tmp");
    let result = write_png_to(image, path, &tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|source| PreviewError::Io {
            path: path.to_owned(),
            source,
        })
    });
    if result.is_err() {
        // Best effort: the temporary file may not exist.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Encodes `image` as an 8-bit RGB PNG into `out` (for callers with their own atomic
/// writer); `path` only labels errors.
pub fn encode_png(image: &Image, path: &Path, out: &mut dyn Write) -> Result<(), PreviewError> {
    let invalid = |message: String| PreviewError::Invalid {
        path: path.to_owned(),
        message,
    };
    if image.width == 0 || image.height == 0 {
        return Err(invalid(format!(
            "image is {}x{}; PNG needs at least 1x1",
            image.width, image.height
        )));
    }
    let expected = image.width as usize * image.height as usize * 3;
    if image.rgb.len() != expected {
        return Err(invalid(format!(
            "image has {} bytes of pixel data; {}x{} RGB needs {expected}",
            image.rgb.len(),
            image.width,
            image.height
        )));
    }
    let png_err = |source| PreviewError::Png {
        path: path.to_owned(),
        source,
    };
    let mut encoder = png::Encoder::new(out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().map_err(png_err)?;
    writer.write_image_data(&image.rgb).map_err(png_err)?;
    writer.finish().map_err(png_err)
}

fn write_png_to(image: &Image, path: &Path, tmp: &Path) -> Result<(), PreviewError> {
    let io_err = |source| PreviewError::Io {
        path: tmp.to_owned(),
        source,
    };
    let file = File::create(tmp).map_err(io_err)?;
    let mut out = BufWriter::new(file);
    encode_png(image, path, &mut out)?;
    out.flush().map_err(io_err)?;
    let file = out.into_inner().map_err(|e| io_err(e.into_error()))?;
    file.sync_all().map_err(io_err)
}
