//! PLY meshes (binary either endianness, or ASCII): positions, optional normals and uvs, faces
//! as triangles (quads and larger polygons split as fans). The header is read by `ply-rs-bw`;
//! the payload is decoded here straight into flat arrays, so no face or vertex allocates (the
//! crate's element API builds one value, and one `Vec` per face list, for each element).

use crate::files::snippet;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, ElementDef, Encoding, PropertyType, ScalarType};

/// The most elements of one kind a file may declare: vertex indices are 32-bit.
const MAX_COUNT: usize = u32::MAX as usize;

/// The fewest vertices a face's index list holds.
const MIN_FACE_VERTICES: usize = 3;

#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<[f32; 3]>,
    /// Empty, or one per position.
    pub normals: Vec<[f32; 3]>,
    /// Empty, or one per position.
    pub uvs: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Decodes a whole PLY file. The error is a message for the caller to put after the file name.
pub fn parse(bytes: &[u8]) -> Result<PlyMesh, String> {
    let mut reader = Reader::new(bytes);
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| {
            let lines: Vec<_> = e
                .to_string()
                .lines()
                .map(|l| snippet(l.trim()).into_owned())
                .collect();
            format!("bad PLY header: {}", lines.join("; "))
        })?;
    let payload = reader.into_inner();
    check_counts(&header.elements)?;
    match header.encoding {
        Encoding::Ascii => decode(
            &header.elements,
            &mut AsciiSource {
                text: payload,
                pos: 0,
            },
        ),
        Encoding::BinaryLittleEndian => decode(
            &header.elements,
            &mut Binary::<false> {
                bytes: payload,
                pos: 0,
            },
        ),
        Encoding::BinaryBigEndian => decode(
            &header.elements,
            &mut Binary::<true> {
                bytes: payload,
                pos: 0,
            },
        ),
    }
}

/// Refuses a count beyond any mesh's before anything is read.
fn check_counts(elements: &ply_rs_bw::ply::KeyMap<ElementDef>) -> Result<(), String> {
    for (name, element) in elements {
        if element.count > MAX_COUNT {
            return Err(format!(
                "the header declares {} '{}' elements; at most {MAX_COUNT} are read",
                element.count,
                snippet(name)
            ));
        }
    }
    Ok(())
}

/// How many of `element` the rest of the body can hold at most, which bounds what is reserved
/// for it: a header may claim 2^32 faces over a body of a few bytes, and the decoding loop
/// then stops at the body's end with a message, having asked for no more memory than the
/// file's size warrants. Each value takes at least its size in binary, a digit and a
/// separator in ASCII; a face's index list its count and three indices.
fn room<S: Scalars>(source: &S, element: &ElementDef) -> usize {
    let face = element.name == "face";
    let each: usize = element
        .properties
        .iter()
        .map(|(property, p)| match &p.data_type {
            PropertyType::Scalar(t) => S::least(t),
            PropertyType::List(count, item) if face && is_index_list(property) => {
                S::least(count) + MIN_FACE_VERTICES * S::least(item)
            }
            PropertyType::List(count, _) => S::least(count),
        })
        .sum();
    // The last ASCII value needs no separator after it.
    (source.remaining() + 1) / each.max(1)
}

fn is_index_list(property: &str) -> bool {
    matches!(property, "vertex_indices" | "vertex_index")
}

fn decode<S: Scalars>(
    elements: &ply_rs_bw::ply::KeyMap<ElementDef>,
    source: &mut S,
) -> Result<PlyMesh, String> {
    let mut mesh = PlyMesh::default();
    let mut vertex_count = None;
    for (name, element) in elements {
        match name.as_str() {
            "vertex" => {
                read_vertices(source, element, &mut mesh)?;
                vertex_count = Some(element.count);
            }
            "face" => {
                let n = vertex_count.ok_or("the face element comes before the vertex element")?;
                read_faces(source, element, n, &mut mesh)?;
            }
            _ => skip_element(source, element)?,
        }
    }
    if vertex_count.is_none() {
        return Err("no vertex element".into());
    }
    Ok(mesh)
}

/// Why a value could not be read.
enum Short {
    End,
    Bad(String),
}

/// A payload read value by value; each encoding is its own type so the decoding loops are
/// compiled for it.
trait Scalars {
    fn scalar(&mut self, ty: &ScalarType) -> Result<f64, Short>;
    /// The bytes not read yet.
    fn remaining(&self) -> usize;
    /// The fewest bytes a value of `ty` takes.
    fn least(ty: &ScalarType) -> usize;
}

struct Binary<'a, const BIG_ENDIAN: bool> {
    bytes: &'a [u8],
    pos: usize,
}

impl<const BIG_ENDIAN: bool> Binary<'_, BIG_ENDIAN> {
    #[inline]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], Short> {
        let raw = self.bytes.get(self.pos..self.pos + N).ok_or(Short::End)?;
        self.pos += N;
        let mut b = [0u8; N];
        b.copy_from_slice(raw);
        if BIG_ENDIAN {
            b.reverse();
        }
        Ok(b)
    }
}

impl<const BIG_ENDIAN: bool> Scalars for Binary<'_, BIG_ENDIAN> {
    #[inline]
    fn scalar(&mut self, ty: &ScalarType) -> Result<f64, Short> {
        Ok(match ty {
            ScalarType::Char => i8::from_le_bytes(self.take()?) as f64,
            ScalarType::UChar => u8::from_le_bytes(self.take()?) as f64,
            ScalarType::Short => i16::from_le_bytes(self.take()?) as f64,
            ScalarType::UShort => u16::from_le_bytes(self.take()?) as f64,
            ScalarType::Int => i32::from_le_bytes(self.take()?) as f64,
            ScalarType::UInt => u32::from_le_bytes(self.take()?) as f64,
            ScalarType::Float => f32::from_le_bytes(self.take()?) as f64,
            ScalarType::Double => f64::from_le_bytes(self.take()?),
        })
    }

    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    fn least(ty: &ScalarType) -> usize {
        match ty {
            ScalarType::Char | ScalarType::UChar => 1,
            ScalarType::Short | ScalarType::UShort => 2,
            ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
            ScalarType::Double => 8,
        }
    }
}

struct AsciiSource<'a> {
    text: &'a [u8],
    pos: usize,
}

impl Scalars for AsciiSource<'_> {
    fn scalar(&mut self, _ty: &ScalarType) -> Result<f64, Short> {
        while self.pos < self.text.len() && self.text[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.text.len() && !self.text[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if self.pos == start {
            return Err(Short::End);
        }
        let tok = String::from_utf8_lossy(&self.text[start..self.pos]);
        tok.parse::<f64>()
            .map_err(|_| Short::Bad(format!("'{}' is not a number", snippet(&tok))))
    }

    fn remaining(&self) -> usize {
        self.text.len().saturating_sub(self.pos)
    }

    fn least(_ty: &ScalarType) -> usize {
        2
    }
}

fn short(what: &str, done: usize, total: usize) -> impl Fn(Short) -> String + '_ {
    move |s| match s {
        Short::End => format!("the file ends after {done} of {total} {what}"),
        Short::Bad(m) => format!("{what} {done}: {m}"),
    }
}

/// Where a vertex property goes.
#[derive(Clone, Copy)]
enum Slot {
    Position(usize),
    Normal(usize),
    Uv(usize),
    Ignore,
}

fn read_vertices<S: Scalars>(
    source: &mut S,
    element: &ElementDef,
    mesh: &mut PlyMesh,
) -> Result<(), String> {
    let mut slots = Vec::with_capacity(element.properties.len());
    let (mut has_pos, mut has_normal, mut has_uv) = ([false; 3], [false; 3], [false; 2]);
    for (name, p) in &element.properties {
        let slot = match name.as_str() {
            "x" => Slot::Position(0),
            "y" => Slot::Position(1),
            "z" => Slot::Position(2),
            "nx" => Slot::Normal(0),
            "ny" => Slot::Normal(1),
            "nz" => Slot::Normal(2),
            "u" | "s" | "texture_u" | "texture_s" => Slot::Uv(0),
            "v" | "t" | "texture_v" | "texture_t" => Slot::Uv(1),
            _ => Slot::Ignore,
        };
        match slot {
            Slot::Position(i) => has_pos[i] = true,
            Slot::Normal(i) => has_normal[i] = true,
            Slot::Uv(i) => has_uv[i] = true,
            Slot::Ignore => {}
        }
        if !matches!(slot, Slot::Ignore) && matches!(p.data_type, PropertyType::List(..)) {
            return Err(format!("vertex property '{}' is a list", snippet(name)));
        }
        slots.push((slot, p.data_type.clone()));
    }
    if has_pos != [true; 3] {
        return Err("the vertex element lacks x, y or z".into());
    }
    let normals = has_normal == [true; 3];
    let uvs = has_uv == [true; 2];
    let n = element.count;
    let fit = n.min(room(source, element));
    mesh.positions.reserve_exact(fit);
    if normals {
        mesh.normals.reserve_exact(fit);
    }
    if uvs {
        mesh.uvs.reserve_exact(fit);
    }
    for i in 0..n {
        let (mut p, mut nn, mut uv) = ([0f32; 3], [0f32; 3], [0f32; 2]);
        for (slot, ty) in &slots {
            let value = match ty {
                PropertyType::Scalar(t) => source.scalar(t),
                PropertyType::List(count_ty, item_ty) => {
                    skip_list(source, count_ty, item_ty).map(|_| 0.0)
                }
            }
            .map_err(short("vertices", i, n))?;
            match *slot {
                Slot::Position(k) => p[k] = value as f32,
                Slot::Normal(k) => nn[k] = value as f32,
                Slot::Uv(k) => uv[k] = value as f32,
                Slot::Ignore => {}
            }
        }
        if !p.iter().all(|x| x.is_finite()) {
            return Err(format!("vertex {i}: position {p:?} is not finite"));
        }
        if normals && !nn.iter().all(|x| x.is_finite()) {
            return Err(format!("vertex {i}: normal {nn:?} is not finite"));
        }
        if uvs && !uv.iter().all(|x| x.is_finite()) {
            return Err(format!("vertex {i}: uv {uv:?} is not finite"));
        }
        mesh.positions.push(p);
        if normals {
            mesh.normals.push(nn);
        }
        if uvs {
            mesh.uvs.push(uv);
        }
    }
    Ok(())
}

fn skip_list<S: Scalars>(
    source: &mut S,
    count_ty: &ScalarType,
    item_ty: &ScalarType,
) -> Result<(), Short> {
    let count = source.scalar(count_ty)?;
    for _ in 0..count.max(0.0) as usize {
        source.scalar(item_ty)?;
    }
    Ok(())
}

fn read_faces<S: Scalars>(
    source: &mut S,
    element: &ElementDef,
    vertex_count: usize,
    mesh: &mut PlyMesh,
) -> Result<(), String> {
    let list = element
        .properties
        .iter()
        .position(|(name, p)| is_index_list(name) && matches!(p.data_type, PropertyType::List(..)))
        .ok_or("the face element has no vertex_indices list")?;
    let n = element.count;
    mesh.triangles.reserve(n.min(room(source, element)));
    for f in 0..n {
        for (k, (_, p)) in element.properties.iter().enumerate() {
            match &p.data_type {
                PropertyType::Scalar(t) => {
                    source.scalar(t).map_err(short("faces", f, n))?;
                }
                PropertyType::List(count_ty, item_ty) if k != list => {
                    skip_list(source, count_ty, item_ty).map_err(short("faces", f, n))?
                }
                PropertyType::List(count_ty, item_ty) => {
                    let count = source.scalar(count_ty).map_err(short("faces", f, n))?;
                    if !(3.0..=1024.0).contains(&count) || count.fract() != 0.0 {
                        return Err(format!("face {f} has {count} vertices"));
                    }
                    let mut first = 0u32;
                    let mut prev = 0u32;
                    for j in 0..count as usize {
                        let x = source.scalar(item_ty).map_err(short("faces", f, n))?;
                        if x.fract() != 0.0 || x < 0.0 || x >= vertex_count as f64 {
                            return Err(format!(
                                "face {f} refers to vertex {x}, but there are {vertex_count}"
                            ));
                        }
                        let index = x as u32;
                        match j {
                            0 => first = index,
                            1 => prev = index,
                            _ => {
                                mesh.triangles.push([first, prev, index]);
                                prev = index;
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

fn skip_element<S: Scalars>(source: &mut S, element: &ElementDef) -> Result<(), String> {
    let what = format!("'{}' elements", snippet(&element.name));
    for i in 0..element.count {
        for (_, p) in &element.properties {
            match &p.data_type {
                PropertyType::Scalar(t) => source.scalar(t).map(|_| ()),
                PropertyType::List(c, t) => skip_list(source, c, t),
            }
            .map_err(short(&what, i, element.count))?;
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A binary little-endian PLY: vertices with normals and uvs, and `faces` as index lists.
    pub fn binary_ply(
        positions: &[[f32; 3]],
        normals: &[[f32; 3]],
        uvs: &[[f32; 2]],
        faces: &[&[u32]],
    ) -> Vec<u8> {
        let mut out = format!(
            "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\n\
             property float nx\nproperty float ny\nproperty float nz\n\
             property float u\nproperty float v\n\
             element face {}\nproperty list uint8 int vertex_indices\nend_header\n",
            positions.len(),
            faces.len()
        )
        .into_bytes();
        for i in 0..positions.len() {
            for x in positions[i].iter().chain(&normals[i]).chain(&uvs[i]) {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        for f in faces {
            out.push(f.len() as u8);
            for i in *f {
                out.extend_from_slice(&(*i as i32).to_le_bytes());
            }
        }
        out
    }

    #[test]
    fn binary_with_normals_uvs_and_a_quad() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let n = [[0.0, 0.0, 1.0]; 4];
        let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let bytes = binary_ply(&p, &n, &uv, &[&[0, 1, 2, 3], &[0, 2, 3]]);
        let mesh = parse(&bytes).unwrap();
        assert_eq!(mesh.positions, p);
        assert_eq!(mesh.normals, n);
        assert_eq!(mesh.uvs, uv);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        // Cut short, and an index out of range.
        let err = parse(&bytes[..bytes.len() - 3]).unwrap_err();
        assert!(err.contains("ends after 1 of 2 faces"), "{err}");
        let bad = binary_ply(&p, &n, &uv, &[&[0, 1, 4]]);
        assert!(parse(&bad).unwrap_err().contains("refers to vertex 4"));
    }

    #[test]
    fn ascii_and_big_endian() {
        let ascii =
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                      property float z\nelement face 1\nproperty list uchar uint vertex_indices\n\
                      end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let mesh = parse(ascii).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        assert!(mesh.normals.is_empty() && mesh.uvs.is_empty());
        let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\n\
                       property double y\nproperty double z\nelement face 1\n\
                       property list uchar ushort vertex_indices\nend_header\n"
            .to_vec();
        for x in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            be.extend_from_slice(&x.to_be_bytes());
        }
        be.push(3);
        for i in [0u16, 1, 2] {
            be.extend_from_slice(&i.to_be_bytes());
        }
        let mesh2 = parse(&be).unwrap();
        assert_eq!(mesh2.positions, mesh.positions);
        assert_eq!(mesh2.triangles, mesh.triangles);
        assert!(parse(b"ply\nformat ascii 1.0\nelement vertex 1\nend_header\n").is_err());
    }

    #[test]
    fn counts_beyond_the_body_end_in_a_message_not_an_allocation() {
        let three = b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        let ply = |vertices: u64, faces: u64| {
            let mut out = format!(
                "ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\n\
                 property float y\nproperty float z\nelement face {faces}\n\
                 property list uchar uint vertex_indices\nend_header\n"
            )
            .into_bytes();
            out.extend_from_slice(three);
            out
        };
        assert_eq!(parse(&ply(3, 1)).unwrap().triangles, vec![[0, 1, 2]]);
        let err = parse(&ply(3, u32::MAX as u64)).unwrap_err();
        assert!(err.contains("ends after 1 of 4294967295 faces"), "{err}");
        let err = parse(&ply(1 << 40, 1)).unwrap_err();
        assert!(err.contains("1099511627776 'vertex' elements"), "{err}");
        // What is reserved is what the body can hold.
        let body = Binary::<false> {
            bytes: &[0; 100],
            pos: 0,
        };
        let header = Parser::<DefaultElement>::new()
            .read_header(&mut Reader::new(&ply(1 << 30, 1 << 30)[..]))
            .unwrap();
        assert_eq!(room(&body, &header.elements["vertex"]), 101 / 12);
        assert_eq!(room(&body, &header.elements["face"]), 101 / 13);
    }

    #[test]
    fn normals_and_uvs_must_be_finite() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let n = [[0.0, 0.0, 1.0]; 3];
        let uv = [[0.0, 0.0]; 3];
        let faces: [&[u32]; 1] = [&[0, 1, 2]];
        assert!(parse(&binary_ply(&p, &n, &uv, &faces)).is_ok());
        let mut bad_n = n;
        bad_n[1][2] = f32::NAN;
        let err = parse(&binary_ply(&p, &bad_n, &uv, &faces)).unwrap_err();
        assert!(err.contains("vertex 1: normal"), "{err}");
        let mut bad_uv = uv;
        bad_uv[2][0] = f32::INFINITY;
        let err = parse(&binary_ply(&p, &n, &bad_uv, &faces)).unwrap_err();
        assert!(err.contains("vertex 2: uv"), "{err}");
    }
}
