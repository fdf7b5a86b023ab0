//! OBJ and MTL files at the boundary with tobj: every line is checked first, with its file and
//! number in the message (tobj's own errors name neither, and some malformed lines make it
//! panic), files are opened only through [`crate::files`], and a panic left in tobj is caught
//! and reported as an error rather than ending the process.

use super::{SceneError, Warning};
use crate::files::{self, excerpt, Kind};
use std::cell::RefCell;
use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// Characters of an input line quoted in a message.
const EXCERPT: usize = 80;

fn at_line(file: &Path, number: usize, entry: String, message: String) -> SceneError {
    SceneError::Invalid {
        file: file.to_path_buf(),
        entry: format!("line {number}{entry}"),
        message,
    }
}

/// What the OBJ check learned: the material names the file uses, with the line of each
/// first use.
pub struct ObjFacts {
    pub usemtl: Vec<(String, usize)>,
}

/// Checks every statement tobj reads: `v` (three finite numbers, then nothing, a non-zero `w`
/// or an RGB triple), `vt`, `vn`, and faces of at least 3 vertices whose indices exist.
pub fn check_obj(path: &Path, text: &str) -> Result<ObjFacts, SceneError> {
    let mut counts = [0usize; 3];
    let mut usemtl: Vec<(String, usize)> = Vec::new();
    // The largest positive index of each kind, checked at the end (OBJ allows forward use).
    let mut largest = [(0usize, 0usize); 3];
    // The words after the keyword, one list for all lines (a large mesh has millions).
    let mut rest: Vec<&str> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let fail = |message: String| {
            Err(at_line(
                path,
                number,
                String::new(),
                format!("{message}: '{}'", excerpt(line.trim(), EXCERPT)),
            ))
        };
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        rest.clear();
        rest.extend(words);
        // The first `n` (at most 4) words as finite numbers.
        let numbers = |n: usize| -> Option<[f32; 4]> {
            let mut values = [0.0; 4];
            for (value, word) in values.iter_mut().zip(rest.get(..n)?) {
                *value = word.parse::<f32>().ok().filter(|x| x.is_finite())?;
            }
            Some(values)
        };
        match keyword {
            "v" => {
                if numbers(3).is_none() {
                    return fail("a vertex needs three finite coordinates".into());
                }
                match rest.len() {
                    3 | 6 => {}
                    4 if numbers(4).is_some_and(|v| v[3] != 0.0) => {}
                    _ => {
                        return fail(
                            "a vertex is x y z, then nothing, a non-zero w, or r g b".into(),
                        )
                    }
                }
                counts[0] += 1;
            }
            "vt" if numbers(2).is_none() => {
                return fail("a texture coordinate needs two finite numbers".into())
            }
            "vt" => counts[1] += 1,
            "vn" if numbers(3).is_none() => {
                return fail("a normal needs three finite numbers".into())
            }
            "vn" => counts[2] += 1,
            "f" | "l" => {
                if keyword == "f" && rest.len() < 3 {
                    return fail(format!(
                        "a face needs at least 3 vertices, this one has {}",
                        rest.len()
                    ));
                }
                for corner in &rest {
                    let mut split = corner.split('/');
                    let parts = [split.next(), split.next(), split.next()];
                    if split.next().is_some() || parts[0].is_none_or(str::is_empty) {
                        return fail(format!("'{corner}' is not v, v/vt, v//vn or v/vt/vn"));
                    }
                    for (kind, part) in parts.into_iter().flatten().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let what = ["vertex", "texture coordinate", "normal"][kind];
                        let Ok(index) = part.parse::<i64>() else {
                            return fail(format!("'{part}' is not a {what} index"));
                        };
                        let defined = counts[kind] as i64;
                        if index == 0 || index < -defined {
                            return fail(format!(
                                "{what} index {index} does not exist ({defined} defined so far)"
                            ));
                        }
                        if index > 0 && index as usize > largest[kind].0 {
                            largest[kind] = (index as usize, number);
                        }
                    }
                }
            }
            "usemtl" | "mtllib" | "o" | "g" if rest.is_empty() => {
                return fail(format!("`{keyword}` needs a name"))
            }
            "usemtl" => {
                let name = rest.join(" ");
                if !usemtl.iter().any(|(n, _)| *n == name) {
                    usemtl.push((name, number));
                }
            }
            _ => {}
        }
    }
    for (kind, (index, number)) in largest.into_iter().enumerate() {
        if index > counts[kind] {
            let what = ["vertex", "texture coordinate", "normal"][kind];
            return Err(at_line(
                path,
                number,
                String::new(),
                format!(
                    "{what} index {index} does not exist (the file defines {})",
                    counts[kind]
                ),
            ));
        }
    }
    Ok(ObjFacts { usemtl })
}

/// Checks every MTL statement tobj reads, like the scene file's values: colours are three
/// finite numbers, albedos (`Kd`, `Ks`) in [0, 1], emission (`Ke`) >= 0, `Ns` finite >= 0, `Ni`
/// finite > 0, `d` in [0, 1], `illum` 0 to 10; a material is defined once, and nothing comes
/// before the first `newmtl`. Returns the material names.
pub fn check_mtl(path: &Path, text: &str) -> Result<Vec<String>, SceneError> {
    let mut defined: HashMap<String, usize> = HashMap::new();
    let mut names = Vec::new();
    let mut current: Option<String> = None;
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        if keyword.starts_with('#') {
            continue;
        }
        let rest: Vec<&str> = words.collect();
        let entry = match &current {
            Some(name) => format!(", material '{name}', {keyword}"),
            None => format!(", {keyword}"),
        };
        let fail = |message: String| {
            Err(at_line(
                path,
                number,
                entry.clone(),
                format!("{message}: '{}'", excerpt(line.trim(), EXCERPT)),
            ))
        };
        if keyword == "newmtl" {
            let name = line.trim()["newmtl".len()..].trim().to_string();
            if name.is_empty() {
                return fail("`newmtl` needs a name".into());
            }
            if let Some(first) = defined.insert(name.clone(), number) {
                return fail(format!(
                    "material '{name}' is already defined on line {first}"
                ));
            }
            names.push(name.clone());
            current = Some(name);
            continue;
        }
        let read = matches!(
            keyword,
            "Ka" | "Kd" | "Ks" | "Ke" | "Ns" | "Ni" | "d" | "illum"
        ) || keyword.starts_with("map_")
            || keyword == "bump";
        if !read {
            continue;
        }
        if current.is_none() {
            return fail("comes before any `newmtl`, so it belongs to no material".into());
        }
        let values: Option<Vec<f32>> = rest.iter().map(|w| w.parse::<f32>().ok()).collect();
        match keyword {
            "Ka" | "Kd" | "Ks" | "Ke" => {
                let Some(v) = values.filter(|v| v.len() == 3) else {
                    return fail("expected three numbers r g b".into());
                };
                if !v.iter().all(|x| x.is_finite()) {
                    return fail("the colour is not finite".into());
                }
                if v.iter().any(|&x| x < 0.0) {
                    return fail("a colour component is negative".into());
                }
                if matches!(keyword, "Kd" | "Ks") && v.iter().any(|&x| x > 1.0) {
                    return fail("an albedo above 1 would create energy".into());
                }
            }
            "Ns" | "Ni" | "d" => {
                let Some(x) = values.filter(|v| v.len() == 1).map(|v| v[0]) else {
                    return fail("expected one number".into());
                };
                let ok = match keyword {
                    "Ns" => x.is_finite() && x >= 0.0,
                    "Ni" => x.is_finite() && x > 0.0,
                    _ => (0.0..=1.0).contains(&x),
                };
                if !ok {
                    let expected = match keyword {
                        "Ns" => "a finite Phong exponent >= 0",
                        "Ni" => "a finite index of refraction > 0",
                        _ => "a dissolve in [0, 1]",
                    };
                    return fail(format!("{x} is not {expected}"));
                }
            }
            "illum" => {
                if !(rest.len() == 1 && rest[0].parse::<u8>().is_ok_and(|n| n <= 10)) {
                    return fail("expected an illumination model 0 to 10".into());
                }
            }
            _ => {
                if rest.is_empty() {
                    return fail("a texture statement needs a file".into());
                }
            }
        }
    }
    Ok(names)
}

/// An MTL file an OBJ loaded: its path and bytes (for the scene's hash) and its materials.
pub struct MtlFile {
    pub path: PathBuf,
    pub bytes: Vec<u8>,
    pub names: Vec<String>,
}

/// What [`load_obj`] returns: tobj's models and materials, and the MTL files read.
pub struct Obj {
    pub models: Vec<tobj::Model>,
    pub materials: Vec<tobj::Material>,
    pub mtl_files: Vec<MtlFile>,
    pub facts: ObjFacts,
}

/// Checks and loads an OBJ (already read as `bytes`) with its MTL files. `entry` names the
/// scene-file entry that refers to it.
pub fn load_obj(
    path: &Path,
    bytes: &[u8],
    options: &tobj::LoadOptions,
    entry: &str,
) -> Result<Obj, SceneError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        at_line(path, line, String::new(), "not UTF-8 text".into())
    })?;
    let facts = check_obj(path, text)?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mtl_files = RefCell::new(Vec::new());
    // tobj's material loader returns tobj's error type; the real error waits here.
    let mtl_error = RefCell::new(None::<SceneError>);
    let load_mtl = |name: &Path| {
        let mtl_path = dir.join(name);
        let result = files::read_text(&mtl_path, Kind::Mtl)
            .map_err(|e| SceneError::Invalid {
                file: mtl_path.clone(),
                entry: format!("mtllib of {} ({entry})", path.display()),
                message: e.message,
            })
            .and_then(|text| {
                let names = check_mtl(&mtl_path, &text)?;
                Ok((text, names))
            });
        match result {
            Ok((text, names)) => {
                let parsed = tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()));
                mtl_files.borrow_mut().push(MtlFile {
                    path: mtl_path,
                    bytes: text.into_bytes(),
                    names,
                });
                parsed
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut Cursor::new(bytes), options, load_mtl)
    }));
    let (models, materials) = match loaded {
        Ok(Ok(result)) => result,
        Ok(Err(e)) => {
            return Err(SceneError::Parse {
                file: path.to_path_buf(),
                message: format!("{entry}: {e}"),
            })
        }
        Err(_) => {
            return Err(SceneError::Parse {
                file: path.to_path_buf(),
                message: format!("{entry}: the OBJ reader panicked on this file"),
            })
        }
    };
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let materials = materials.map_err(|e| SceneError::Parse {
        file: path.to_path_buf(),
        message: format!("{entry}: its MTL file: {e}"),
    })?;
    Ok(Obj {
        models,
        materials,
        mtl_files: mtl_files.into_inner(),
        facts,
    })
}

/// A warning for every `usemtl` naming a material neither the MTL files nor the scene file
/// define (a typo would otherwise only show as grey surfaces).
pub fn unknown_usemtl(path: &Path, obj: &Obj, scene_materials: &[String]) -> Vec<Warning> {
    let known: Vec<&str> = obj
        .mtl_files
        .iter()
        .flat_map(|m| m.names.iter().map(String::as_str))
        .chain(scene_materials.iter().map(String::as_str))
        .collect();
    obj.facts
        .usemtl
        .iter()
        .filter(|(name, _)| !known.contains(&name.as_str()))
        .map(|(name, line)| {
            Warning::file(
                path,
                format!(
                    "line {line}: usemtl '{}' names no material (known: {}); its faces get the default grey",
                    excerpt(name, EXCERPT),
                    known.join(", ")
                ),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj_error(text: &str) -> String {
        match check_obj(Path::new("m.obj"), text) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted: {text}"),
        }
    }

    fn mtl_error(text: &str) -> String {
        match check_mtl(Path::new("m.mtl"), text) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted: {text}"),
        }
    }

    #[test]
    fn obj_lines_are_checked_with_their_number() {
        let good = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf -3 -2 -1\n";
        assert!(check_obj(Path::new("m.obj"), good).is_ok());
        assert!(obj_error("v 0 0 0\nv 1 0 0\nf 1 2\n").contains("line 3"));
        assert!(obj_error("v 0 0\n").contains("line 1"));
        assert!(obj_error("v 0 0 nan\n").contains("finite"));
        assert!(obj_error("v 0 0 0 0\n").contains("non-zero w"));
        assert!(obj_error("v 0 0 0\nf 1 1 0\n").contains("index 0"));
        assert!(obj_error("v 0 0 0\nf 1 1 9\n").contains("index 9"));
        assert!(obj_error("v 0 0 0\nf 1 1 -4\n").contains("index -4"));
        assert!(obj_error("v 0 0 0\nf 1/2/3/4 1 1\n").contains("not v"));
    }

    #[test]
    fn mtl_values_are_checked_like_scene_values() {
        assert!(check_mtl(Path::new("m.mtl"), "newmtl a\nKd 0.5 0.5 0.5\nNs 10\n").is_ok());
        assert!(mtl_error("newmtl a\nKd 0.5 0.5\n").contains("three numbers"));
        assert!(mtl_error("newmtl a\nKd 1.5 0.5 0.5\n").contains("albedo"));
        assert!(mtl_error("newmtl a\nNs -10\n").contains("exponent"));
        assert!(mtl_error("newmtl a\nNs 1e39\n").contains("exponent"));
        assert!(mtl_error("newmtl a\nNi 0\n").contains("refraction"));
        assert!(mtl_error("newmtl a\nNi nan\n").contains("refraction"));
        assert!(mtl_error("newmtl a\nKe inf 0 0\n").contains("finite"));
        assert!(mtl_error("newmtl a\nnewmtl a\n").contains("line 1"));
        assert!(mtl_error("Kd 0.5 0.5 0.5\n").contains("before any"));
        let long = format!("newmtl a\nKd {}\n", "1 ".repeat(100_000));
        assert!(mtl_error(&long).len() < 400);
    }
}
