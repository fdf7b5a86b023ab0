//! The options table ([`vmerge::options::OPTIONS`]): for every technique and every option it
//! takes, at values other than the default (the edges of each range among them), options
//! written as command-line arguments read back as the same options; options a technique does
//! not take are refused.

use vmerge::options::{
    MemoryLayout, OptionError, OptionName, OptionSpec, RenderOptions, Technique, OPTIONS,
};

/// Values other than the default for each option, as arguments write them: the edges of its
/// valid range and values inside it. A switch has one, "on".
fn values(name: &str) -> Vec<String> {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let (u32_max, u64_max) = (u32::MAX.to_string(), u64::MAX.to_string());
    let (f_min, f_max) = (f32::MIN_POSITIVE.to_string(), f32::MAX.to_string());
    match name {
        "technique" => Technique::ALL[1..]
            .iter()
            .map(|t| t.name().into())
            .collect(),
        "seed" => vec!["1".into(), "4294967296".into(), u64_max],
        "camera" => s(&["front", "1", "a camera, with spaces"]),
        "resolution" => vec!["1x1".into(), "640x480".into(), format!("{u32_max}x1")],
        "beta" => vec!["0".into(), "1".into(), "0.5".into(), f_min, f_max],
        "radius" => vec![f_min, "0.003".into(), "1".into(), f_max],
        "radius_pixels" => vec![f_min, "0.5".into(), "3".into(), f_max],
        "alpha" => vec![f_min, "0.25".into(), "0.75".into(), "1".into()],
        "max_path_length" | "roulette" => vec!["0".into(), "1".into(), "7".into(), u32_max],
        "min_path_length" => vec!["1".into(), "2".into(), "3".into(), u32_max],
        "light_paths" | "upg_max_trials" | "density_map_iterations" => {
            vec!["1".into(), "2".into(), "1000".into(), u32_max]
        }
        "strategy" => vec![
            "0,2".into(),
            "1,1".into(),
            "2,1".into(),
            format!("{u32_max},{u32_max}"),
        ],
        "upg_packet" => s(&["8"]),
        // Each with the other at its default (4 to 12 radii), and pairwise in order.
        "blend_near" => s(&["0", "0.5", "5.5"]),
        "blend_far" => vec!["4.5".into(), "10".into(), f_max],
        "hybrid_roughness" => vec!["0".into(), f_min, "0.05".into(), "1".into(), f_max],
        "sampler" => s(&["independent"]),
        "density_mis" => s(&["vcm+", "vcm*"]),
        "memory" => s(&["one-stage"]),
        "no_vc" | "no_vm" | "unweighted" | "no_shading_normals" => s(&["true"]),
        other => panic!("no test values for option '{other}': add them"),
    }
}

/// The default options of `technique` with `spec` set to `value`, read as the command line
/// reads it.
fn with(technique: Technique, spec: &OptionSpec, value: &str) -> RenderOptions {
    let mut o = RenderOptions {
        technique,
        ..RenderOptions::DEFAULT
    };
    spec.read(&mut o, value)
        .unwrap_or_else(|e| panic!("{technique} {}: {e}", spec.name));
    o
}

fn round_trip(o: &RenderOptions) {
    let args = o.to_args();
    let back = RenderOptions::from_args(&args).unwrap_or_else(|e| panic!("{args:?}: {e}"));
    assert_eq!(&back, o, "{args:?}");
}

#[test]
fn every_option_a_technique_takes_survives_the_command_line() {
    let mut checked = 0;
    for technique in Technique::ALL {
        round_trip(&RenderOptions {
            technique,
            ..RenderOptions::DEFAULT
        });
        for spec in OPTIONS.iter().filter(|s| (s.takes)(technique)) {
            for value in values(spec.name) {
                let o = with(technique, spec, &value);
                if spec.name != "technique" {
                    assert!(spec.is_set(&o), "{technique} {} {value}", spec.name);
                    assert_eq!(o.validate(), Ok(()), "{technique} {} {value}", spec.name);
                    assert_eq!((spec.write)(&o).as_deref(), Some(value.as_str()));
                }
                round_trip(&o);
                checked += 1;
            }
        }
    }
    assert!(checked > 100, "{checked}");
}

/// Every option a technique takes at once, each at each of its values in turn (the last value
/// where an option has fewer), so that options are read independently of each other.
#[test]
fn all_options_of_a_technique_together_survive_the_command_line() {
    for technique in Technique::ALL {
        let specs: Vec<&OptionSpec> = OPTIONS
            .iter()
            .filter(|s| (s.takes)(technique) && s.name != "technique")
            .collect();
        let rounds = specs.iter().map(|s| values(s.name).len()).max().unwrap();
        for round in 0..rounds {
            let mut o = RenderOptions {
                technique,
                ..RenderOptions::DEFAULT
            };
            for spec in &specs {
                let values = values(spec.name);
                spec.read(&mut o, &values[round.min(values.len() - 1)])
                    .unwrap();
            }
            // A per-pixel radius stands in for the global one, without 002's weights: every
            // other round takes it.
            if o.radius_pixels.is_some() {
                if round % 2 == 0 {
                    o.radius_pixels = None;
                } else {
                    o.radius = None;
                    o.density_mis = None;
                }
            }
            // 002's weights weigh merges, which no_vm leaves out.
            o.no_vm &= o.density_mis.is_none();
            // One-stage merges take one light sub-path per pixel, no density map and a global
            // radius.
            if o.density_mis.is_some() || o.light_paths.is_some() || o.radius_pixels.is_some() {
                o.memory = MemoryLayout::TwoStage;
            }
            assert_eq!(o.validate(), Ok(()), "{technique} {o:?}");
            round_trip(&o);
        }
    }
}

#[test]
fn options_a_technique_does_not_take_are_refused() {
    let mut refused = 0;
    for technique in Technique::ALL {
        for spec in OPTIONS.iter().filter(|s| !(s.takes)(technique)) {
            for value in values(spec.name) {
                let o = with(technique, spec, &value);
                // The command line reads them, and validation refuses them.
                round_trip(&o);
                match o.validate() {
                    Err(OptionError::NotTaken {
                        option: OptionName(name),
                        technique: t,
                        takes,
                    }) => {
                        assert_eq!((name, t), (spec.name, technique));
                        assert!(takes.iter().all(|&t| (spec.takes)(t)));
                    }
                    other => panic!("{technique} {} {value}: {other:?}", spec.name),
                }
                refused += 1;
            }
        }
    }
    assert!(refused > 50, "{refused}");
}

#[test]
fn values_out_of_range_and_unreadable_arguments_are_refused() {
    let vcm = RenderOptions {
        technique: Technique::Vcm,
        ..RenderOptions::DEFAULT
    };
    for (args, option) in [
        (&["--radius", "0"][..], "radius"),
        (&["--alpha", "1.5"], "alpha"),
        (&["--beta", "-1"], "beta"),
        (&["--light-paths", "0"], "light_paths"),
        (&["--density-map-iterations", "0"], "density_map_iterations"),
        (&["--density-mis", "vcm+", "--no-vm"], "density_mis"),
    ] {
        let mut all = vcm.to_args();
        all.extend(args.iter().map(|a| a.to_string()));
        let o = RenderOptions::from_args(&all).unwrap();
        assert!(
            matches!(o.validate(), Err(OptionError::OutOfRange { option: OptionName(n), .. }) if n == option),
            "{args:?}: {:?}",
            o.validate()
        );
    }
    for args in [
        &["--resolution", "0x4"][..],
        &["--strategy", "two"],
        &["--sampler", "halton"],
        &["--density-mis", "vcm"],
        &["--roulette", "-1"],
        &["--upg-packet"],
        &["--no-such-option"],
    ] {
        assert!(RenderOptions::from_args(args).is_err(), "{args:?}");
    }
}

/// A batch cell's name carries every option that changes the image apart from those it names
/// on its own (radius, seed, camera) and the resolution: two values give two names, and every
/// name is a plain file name.
#[test]
fn batch_variant_names_tell_every_value_apart() {
    use vmerge::tools::batch::variant_name;
    let mut names = std::collections::BTreeMap::new();
    for technique in Technique::ALL {
        let default = RenderOptions {
            technique,
            ..RenderOptions::DEFAULT
        };
        names.insert(variant_name(&default), format!("{technique}"));
        for spec in OPTIONS.iter().filter(|s| (s.takes)(technique)) {
            if matches!(
                spec.name,
                "technique" | "seed" | "camera" | "radius" | "resolution"
            ) {
                continue;
            }
            for value in values(spec.name) {
                let o = with(technique, spec, &value);
                let name = variant_name(&o);
                assert!(
                    name.chars()
                        .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)),
                    "{name}"
                );
                let what = format!("{technique} {} {value}", spec.name);
                if let Some(earlier) = names.insert(name.clone(), what.clone()) {
                    panic!("{what} and {earlier} are both named {name}");
                }
            }
        }
    }
}
