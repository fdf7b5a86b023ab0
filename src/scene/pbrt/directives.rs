//! Every pbrt-v4 directive vmerge knows, in one table: what follows its name (the parser
//! checks it), where in the file it may stand, and what the importer does with it. A name not
//! in the table is skipped with a warning.

use super::import::{Importer, Loc};
use super::parser::Directive;
use crate::scene::SceneError;

/// What follows a directive's name.
#[derive(Clone, Copy, Debug)]
pub enum Form {
    Nothing,
    Numbers(usize),
    /// 16 numbers, bracketed or not.
    Matrix,
    Strings(usize),
    /// One bare word (ActiveTransform).
    Word,
    /// `n` strings, then parameters.
    StringsParams(usize),
    /// One or two strings (MediumInterface).
    OneOrTwoStrings,
    ParamsOnly,
}

/// Where in the file a directive may stand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// Before WorldBegin: the camera and the render's settings.
    Options,
    /// After WorldBegin: the scene's content.
    World,
    Anywhere,
}

/// What the importer does with a directive at a place in a file.
pub type Handler = fn(&mut Importer, Loc, &Directive) -> Result<(), SceneError>;

pub struct Spec {
    pub name: &'static str,
    pub form: Form,
    pub place: Place,
    pub run: Handler,
}

const fn spec(name: &'static str, form: Form, place: Place, run: Handler) -> Spec {
    Spec {
        name,
        form,
        place,
        run,
    }
}

use Form::*;
use Place::*;

const DIRECTIVES: &[Spec] = &[
    // The render's settings.
    spec("Camera", StringsParams(1), Options, Importer::camera),
    spec("Film", StringsParams(1), Options, Importer::film),
    spec(
        "Integrator",
        StringsParams(1),
        Options,
        Importer::integrator,
    ),
    spec("Sampler", StringsParams(1), Options, Importer::ignored),
    spec("PixelFilter", StringsParams(1), Options, Importer::ignored),
    spec("Accelerator", StringsParams(1), Options, Importer::ignored),
    spec("ColorSpace", Strings(1), Anywhere, Importer::ignored),
    spec("Option", ParamsOnly, Anywhere, Importer::ignored),
    // What vmerge cannot render yet: each warned at its line.
    spec(
        "MakeNamedMedium",
        StringsParams(1),
        Anywhere,
        Importer::unsupported,
    ),
    spec(
        "MediumInterface",
        OneOrTwoStrings,
        Anywhere,
        Importer::unsupported,
    ),
    spec(
        "Attribute",
        StringsParams(1),
        Anywhere,
        Importer::unsupported,
    ),
    // Files and blocks.
    spec("Include", Strings(1), Anywhere, Importer::include),
    spec("Import", Strings(1), Anywhere, Importer::include),
    spec("WorldBegin", Nothing, Anywhere, Importer::world_begin),
    spec("WorldEnd", Nothing, Anywhere, Importer::nothing),
    spec("AttributeBegin", Nothing, World, Importer::begin_block),
    spec("AttributeEnd", Nothing, World, Importer::end_block),
    spec("TransformBegin", Nothing, Anywhere, Importer::begin_block),
    spec("TransformEnd", Nothing, Anywhere, Importer::end_block),
    spec("ObjectBegin", Strings(1), World, Importer::object_begin),
    spec("ObjectEnd", Nothing, World, Importer::object_end),
    spec(
        "ObjectInstance",
        Strings(1),
        World,
        Importer::object_instance,
    ),
    // Transforms.
    spec("Identity", Nothing, Anywhere, Importer::identity),
    spec("Translate", Numbers(3), Anywhere, Importer::translate),
    spec("Scale", Numbers(3), Anywhere, Importer::scale),
    spec("Rotate", Numbers(4), Anywhere, Importer::rotate),
    spec("LookAt", Numbers(9), Anywhere, Importer::look_at),
    spec("Transform", Matrix, Anywhere, Importer::transform),
    spec("ConcatTransform", Matrix, Anywhere, Importer::transform),
    spec(
        "CoordinateSystem",
        Strings(1),
        Anywhere,
        Importer::coordinate_system,
    ),
    spec(
        "CoordSysTransform",
        Strings(1),
        Anywhere,
        Importer::coord_sys_transform,
    ),
    spec(
        "ActiveTransform",
        Word,
        Anywhere,
        Importer::active_transform,
    ),
    spec("TransformTimes", Numbers(2), Anywhere, Importer::nothing),
    spec(
        "ReverseOrientation",
        Nothing,
        World,
        Importer::reverse_orientation,
    ),
    // The scene's content.
    spec(
        "MakeNamedMaterial",
        StringsParams(1),
        World,
        Importer::make_named_material,
    ),
    spec(
        "Material",
        StringsParams(1),
        World,
        Importer::material_directive,
    ),
    spec("NamedMaterial", Strings(1), World, Importer::named_material),
    spec("Texture", StringsParams(3), World, Importer::texture),
    spec(
        "LightSource",
        StringsParams(1),
        World,
        Importer::light_source,
    ),
    spec(
        "AreaLightSource",
        StringsParams(1),
        World,
        Importer::area_light_source,
    ),
    spec("Shape", StringsParams(1), World, Importer::shape),
];

/// The directive named `name`, if vmerge knows it.
pub fn find(name: &str) -> Option<&'static Spec> {
    DIRECTIVES.iter().find(|s| s.name == name)
}

#[cfg(test)]
mod tests {
    #[test]
    fn each_directive_is_listed_once() {
        let mut names: Vec<_> = super::DIRECTIVES.iter().map(|s| s.name).collect();
        let n = names.len();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), n);
        assert!(super::find("Shape").is_some() && super::find("Shapes").is_none());
    }
}
