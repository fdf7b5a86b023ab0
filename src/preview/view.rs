//! The page for finished renders: any RGB EXR, with vmerge's metadata and error series where
//! the file has them.

use super::server::{Content, Server, StateQuery};
use super::{error_rows, ImageData, PreviewError};
use crate::film::{exr, metadata::attribute, FilmError};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

struct Entry {
    name: String,
    image: ImageData,
    rows: Vec<(String, String)>,
    errors: Vec<[f64; 4]>,
}

struct Files {
    entries: Vec<Entry>,
}

impl Content for Files {
    fn state(&self, _: StateQuery) -> String {
        let e = &self.entries;
        let title = match &e[..] {
            [one] => one.name.clone(),
            _ => format!("{} files", e.len()),
        };
        serde_json::json!({
            "mode": "view",
            "title": title,
            "frame": 1,
            "finished": true,
            "images": e.iter().map(|f| serde_json::json!({
                "name": f.name,
                "iteration": f.image.iteration,
                "width": f.image.width,
                "height": f.image.height,
            })).collect::<Vec<_>>(),
            "info": e.iter().map(|f| serde_json::json!({ "name": f.name, "rows": f.rows })).collect::<Vec<_>>(),
            "series": e.iter().map(|f| serde_json::json!({ "name": f.name, "from": 0, "rows": f.errors })).collect::<Vec<_>>(),
        })
        .to_string()
    }

    fn image(&self, index: usize) -> Option<ImageData> {
        self.entries.get(index).map(|e| e.image.clone())
    }
}

/// Finished renders, read and ready to serve.
pub struct Viewer {
    files: Arc<Files>,
}

impl Viewer {
    /// Reads `paths`: vmerge renders with their metadata, other EXRs as plain images.
    pub fn load(paths: &[PathBuf]) -> Result<Self, FilmError> {
        let mut entries = Vec::with_capacity(paths.len());
        for path in paths {
            let name = path.to_string_lossy().into_owned();
            let entry = match exr::read_render(path) {
                Ok((film, metadata)) => Entry {
                    name,
                    image: ImageData::from_sums(
                        film.width,
                        film.height,
                        film.iterations,
                        &film.sum,
                    ),
                    // Options that cannot be written as text leave the table empty, not the page.
                    rows: metadata
                        .to_attributes()
                        .unwrap_or_default()
                        .into_iter()
                        .filter(|(key, _)| *key != attribute::ERRORS)
                        .map(|(key, value)| {
                            (
                                key.strip_prefix(attribute::PREFIX)
                                    .unwrap_or(key)
                                    .to_string(),
                                value,
                            )
                        })
                        .collect(),
                    errors: error_rows(&metadata.errors),
                },
                Err(FilmError::NotARender { .. }) => {
                    let image = exr::read_image(path)?;
                    Entry {
                        name,
                        image: ImageData::from_rgb(image.width, image.height, 0, &image.pixels),
                        rows: vec![("vmerge metadata".into(), "none (a plain EXR)".into())],
                        errors: Vec::new(),
                    }
                }
                Err(e) => return Err(e),
            };
            entries.push(entry);
        }
        Ok(Viewer {
            files: Arc::new(Files { entries }),
        })
    }

    /// Serves the page at `address` until the returned server is dropped.
    pub fn serve(&self, address: SocketAddr) -> Result<Server, PreviewError> {
        Server::start(address, self.files.clone())
    }
}
