//! What a bake can be asked, each option once ([`BakeOptions`], as [`quatcurve_eval::options`] says):
//! the options that decide a bake's outputs, which the manifest records and `resume` compares.
//! Which inputs, where to, which shard and how many at once are the job's ([`super::BakeJob`]).

use super::budget::{ErrorBudget, DEFAULT_MAX_RATE};
use super::image::{Format, DEFAULT_MAX_TEXTURE_SIZE};
use super::player::Player;
use super::root_motion::RootMotion;
use super::texture::{Precision, TextureKind};
use super::ClipRate;
use quatcurve_anim::curves::CurveChoice;
use quatcurve_anim::loops::LoopMode;
use quatcurve_core::curve::Curve;
use quatcurve_device::DeviceChoice;
#[cfg(feature = "cli")]
use quatcurve_eval::options::names;
use quatcurve_eval::options::CurveOptions;
use quatcurve_files::FileJobError;
use quatcurve_formats::crowd;
use quatcurve_formats::source::Source;
use serde::{Deserialize, Serialize};

/// The options of a bake (DESIGN section 6).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct BakeOptions {
    /// Output rate in Hz, fitted per clip so that its first and last frames are its first and
    /// last keys (the clip's own rate is in the sidecar).
    #[cfg_attr(feature = "cli", arg(long, value_name = "HZ", default_value_t = BakeOptions::DEFAULT.rate, allow_negative_numbers = true))]
    pub rate: f64,
    /// Bake every clip at exactly the rate: frames start + i / rate while not past the last key,
    /// so a clip's end off that grid is not baked (the summary warns how much); a loop's frames
    /// stay on its looping curve.
    #[cfg_attr(feature = "cli", arg(long))]
    pub exact_rate: bool,
    /// Curve family for every channel; by default each channel as its source plays it (glTF's
    /// samplers: LINEAR slerp and lerp, STEP, CUBICSPLINE; the frames of BVH, FBX and SMPL
    /// slerped), and bspline-interp (C2, through every key) for the built-in crowd.
    #[cfg_attr(feature = "cli", arg(long, value_parser = names::<Curve>()))]
    pub curve: Option<Curve>,
    /// The family's options (knots: phantom unless given).
    #[serde(flatten)]
    #[cfg_attr(feature = "cli", command(flatten))]
    pub curve_options: CurveOptions,
    /// Which clips loop: auto (those whose rotation channels end on their first rotation), on
    /// (every clip; one that does not close is an error), off.
    #[serde(rename = "loop")]
    #[cfg_attr(feature = "cli", arg(long = "loop", default_value_t = BakeOptions::DEFAULT.looping, value_parser = names::<LoopMode>()))]
    pub looping: LoopMode,
    /// Evaluation device: auto is a hardware GPU if any, else the fast CPU path (also over a
    /// software adapter such as lavapipe; gpu still takes one). The outputs record it.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.device, value_parser = names::<DeviceChoice>()))]
    pub device: DeviceChoice,
    /// Read glTF buffers from anywhere the URI points (absolute paths, `..` out of the file's
    /// directory, `file:` URIs). Off by default: only data URIs and files beside the input.
    #[cfg_attr(feature = "cli", arg(long))]
    pub allow_external_uris: bool,
    /// Bake for this player: the texture, format and atlas it plays where they are left at
    /// their defaults (three: skin-trs EXR, one atlas; babylon: skin as Babylon's JSON; view:
    /// skin-trs EXR); a texture or format it cannot play is refused.
    #[cfg_attr(feature = "cli", arg(long, value_parser = names::<Player>()))]
    pub player: Option<Player>,
    /// Texture per clip: local (rotation, translation, scale of each joint relative to its
    /// parent), model (3x4 matrices relative to the scene root, by forward kinematics), skin
    /// (model times inverse bind matrix, one texture per glTF skin; BVH and the crowd: model),
    /// or model-trs and skin-trs (those transforms as rotation, translation, scale: what a
    /// shader interpolates between frames without shearing; `quatcurve shaders`), or vertex
    /// (glTF and FBX: every skinned mesh primitive skinned at every frame on the device, positions
    /// and normals; images hold them encoded, and `<stem>.mesh.glb` is the mesh they play).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.texture, value_parser = names::<TextureKind>()))]
    pub texture: TextureKind,
    /// Texture element type: f32, or f16 (half the bytes, about 3 significant digits).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.precision, value_parser = names::<Precision>()))]
    pub precision: Precision,
    /// Texture file format: npy arrays, or 2D RGBA images engines import: exr (float, or half
    /// with precision f16) or png16 (16-bit, each channel remapped to its range in the sidecar);
    /// or babylon (Babylon.js's baked vertex animation JSON, of skin textures).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.format, value_parser = names::<Format>()))]
    pub format: Format,
    /// Largest side of an image texture in texels (exr, png16, babylon); frames that do not fit are an error.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.max_texture_size, value_name = "TEXELS"))]
    pub max_texture_size: usize,
    /// One texture per input with every clip stacked along frames (`<stem>.npy`; each clip's
    /// rows from `first_row` in the sidecar), instead of one per clip.
    #[cfg_attr(feature = "cli", arg(long))]
    pub atlas: bool,
    /// Also draw each clip's skeleton at evenly spaced frames, front and side views, to
    /// `<stem>.<clip>.preview.png` (cargo feature `plot`).
    #[cfg_attr(feature = "cli", arg(long))]
    pub preview: bool,
    /// Also write the bake as OpenUSD skeletal animation, `<stem>.usda`: the skeleton, and
    /// each clip a `SkelAnimation` chosen by the skeleton's variant set `clip`.
    #[cfg_attr(feature = "cli", arg(long))]
    pub usd: bool,
    /// Characters in the built-in crowd (baked when no input is named).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.characters))]
    pub characters: usize,
    /// Rotation error budget in degrees: each clip at the lowest rate whose frames, blended
    /// as `quatcurve shaders` does, stay within it of the curve between frames (16 points
    /// per frame interval, every joint); replaces the rate. Textures local, model-trs, skin-trs.
    #[cfg_attr(feature = "cli", arg(long, value_name = "DEG", allow_negative_numbers = true))]
    pub max_error_deg: Option<f64>,
    /// Position budget in cm, for joints in model space (local textures: errors accumulated
    /// down the hierarchy by forward kinematics); with or without the rotation budget.
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", allow_negative_numbers = true))]
    pub max_error_cm: Option<f64>,
    /// The length of one file unit in cm (default: glTF's metre, 100). BVH files and fitted
    /// containers do not say theirs, so such an input needs it (CMU's BVH is 5.644).
    #[cfg_attr(feature = "cli", arg(long, value_name = "CM", allow_negative_numbers = true))]
    pub unit_cm: Option<f64>,
    /// The highest rate a budget may choose (Hz); a clip no rate up to it holds is refused.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.max_rate, value_name = "HZ"))]
    pub max_rate: f64,
    /// keep: the root's horizontal translation and heading stay in the textures; extract: they
    /// go to a per-frame root track in the sidecar (position, heading, velocities; a loop's
    /// per-cycle displacement), and the textures play in place.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = BakeOptions::DEFAULT.root_motion, value_parser = names::<RootMotion>()))]
    pub root_motion: RootMotion,
}

impl BakeOptions {
    /// Every option's default.
    pub const DEFAULT: Self = Self {
        rate: quatcurve_eval::sampling::DEFAULT_RATE,
        exact_rate: false,
        curve: None,
        curve_options: CurveOptions::DEFAULT,
        looping: LoopMode::Auto,
        device: DeviceChoice::Auto,
        allow_external_uris: false,
        player: None,
        texture: TextureKind::Local,
        precision: Precision::F32,
        format: Format::Npy,
        max_texture_size: DEFAULT_MAX_TEXTURE_SIZE,
        atlas: false,
        preview: false,
        usd: false,
        characters: crowd::CHARACTERS,
        max_error_deg: None,
        max_error_cm: None,
        unit_cm: None,
        max_rate: DEFAULT_MAX_RATE,
        root_motion: RootMotion::Keep,
    };

    /// These options with [`Self::player`]'s texture, format and atlas where they are left at
    /// their defaults; the same options again for a bake already resolved.
    ///
    /// # Errors
    /// [`FileJobError::Option`] (`player`) naming every texture or format given that the player
    /// cannot play.
    pub fn for_player(&self) -> Result<Self, FileJobError> {
        let Some(player) = self.player else { return Ok(self.clone()) };
        let plays = player.plays();
        let mut resolved = self.clone();
        if resolved.texture == Self::DEFAULT.texture && !plays.textures.contains(&resolved.texture) {
            resolved.texture = plays.textures[0];
        }
        if resolved.format == Self::DEFAULT.format && !plays.formats.contains(&resolved.format) {
            resolved.format = plays.formats[0];
        }
        resolved.atlas |= plays.atlas;
        let refusals = player.refusals(resolved.texture, resolved.format);
        if refusals.is_empty() {
            return Ok(resolved);
        }
        let words: Vec<String> = refusals.iter().map(ToString::to_string).collect();
        Err(FileJobError::option("player", format!("{player}: {}", words.join("; "))))
    }

    /// What `source`'s keys are interpolated with: the family asked for, else the source's
    /// own choice ([`quatcurve_formats::source::Input::default_curve`]).
    #[must_use]
    pub fn choice(&self, source: &Source) -> CurveChoice {
        self.choice_or(source.default_curve())
    }

    /// What keys are interpolated with: the family asked for, else `default` (`None`: each
    /// channel as its source interpolates it).
    #[must_use]
    pub fn choice_or(&self, default: Option<Curve>) -> CurveChoice {
        CurveChoice::new(self.curve.or(default), &self.curve_options)
    }

    /// How each clip's frames are laid: at the rate exactly, or fitted to the clip.
    #[must_use]
    pub fn clip_rate(&self) -> ClipRate {
        if self.exact_rate {
            ClipRate::Exact(self.rate)
        } else {
            ClipRate::Fit(self.rate)
        }
    }

    /// The error budget that chooses each clip's rate (none set: every clip at `rate`); lengths
    /// in glTF's metre where no unit is given (the job refuses inputs that need one first).
    #[must_use]
    pub fn budget(&self) -> ErrorBudget {
        ErrorBudget {
            degrees: self.max_error_deg,
            centimetres: self.max_error_cm,
            unit_cm: self.unit_cm.unwrap_or(quatcurve_anim::GLTF_UNIT_CM),
            max_rate: self.max_rate,
        }
    }
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_core::curve::KnotMode;
    use quatcurve_eval::options::{from_named, OptionError};

    fn given(json: &str) -> Result<BakeOptions, OptionError> {
        from_named(&serde_json::from_str(json).unwrap())
    }

    #[test]
    fn options_by_name_take_the_defaults_they_are_not_given_and_name_what_is_wrong() {
        assert_eq!(given("{}"), Ok(BakeOptions::DEFAULT));
        let o = given(r#"{"rate": 24, "loop": "on", "texture": "skin-trs", "knots": "uniform", "max_error_deg": 0.5}"#)
            .unwrap();
        assert_eq!(
            (o.rate, o.looping, o.texture, o.curve_options.knots, o.max_error_deg),
            (24.0, LoopMode::On, TextureKind::SkinTrs, KnotMode::Uniform, Some(0.5))
        );
        assert_eq!(BakeOptions { rate: 24.0, ..o.clone() }, o);
        let bad = given(r#"{"rate": 24, "texture": "pretty"}"#).unwrap_err().to_string();
        assert!(bad.starts_with("texture: unknown texture 'pretty' (expected one of: local, "), "{bad}");
        // The field's Rust name is not the option's name.
        assert!(matches!(given(r#"{"looping": "on"}"#), Err(OptionError::Unknown { name, .. }) if name == "looping"));
        let bad = given(r#"{"characters": -3}"#).unwrap_err().to_string();
        assert!(bad.starts_with("characters: invalid value: integer `-3`"), "{bad}");
    }

    #[test]
    fn the_options_written_read_back_as_themselves() {
        let o = BakeOptions {
            exact_rate: true,
            max_error_cm: Some(3.0),
            root_motion: RootMotion::Extract,
            ..BakeOptions::DEFAULT
        };
        let written = serde_json::to_value(&o).unwrap();
        assert_eq!(written["loop"], "auto");
        assert_eq!(serde_json::from_value::<BakeOptions>(written).unwrap(), o);
    }

    /// Every option is a flag of the command line, spelled from its name.
    #[cfg(feature = "cli")]
    #[test]
    fn every_option_is_a_flag_named_after_it() {
        use clap::Args;
        let command = BakeOptions::augment_args(clap::Command::new("bake"));
        let flags: Vec<String> = command.get_arguments().filter_map(|a| a.get_long().map(str::to_string)).collect();
        let serde_json::Value::Object(names) = serde_json::to_value(BakeOptions::DEFAULT).unwrap() else { panic!() };
        let mut names: Vec<String> = names.keys().map(|n| n.replace('_', "-")).collect();
        let mut flags = flags;
        names.sort();
        flags.sort();
        assert_eq!(flags, names);
    }
}
