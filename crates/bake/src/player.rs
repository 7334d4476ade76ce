//! The players a bake is made for ([`Player`]): which textures and formats each plays, so that
//! one option gives a bake its player opens, and a bake it cannot open is named with every
//! reason at once.

use super::image::Format;
use super::texture::TextureKind;
use quatcurve_eval::error::one_of;

/// A player of bakes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Player {
    /// three.js, through `packages/quatcurve-three`.
    Three,
    /// Babylon.js's own `BakedVertexAnimationManager`.
    Babylon,
    /// `quatcurve view`'s page.
    View,
}

quatcurve_core::curve::names!(Player, "player", Three => "three", Babylon => "babylon", View => "view");

/// What a player plays; the first texture and format are the ones a bake for it gets when the
/// bake leaves them at their defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plays {
    /// The texture kinds it plays.
    pub textures: &'static [TextureKind],
    /// The file formats it reads.
    pub formats: &'static [Format],
    /// Whether a bake for it stacks every clip in one texture (three.js: instances of
    /// different clips share one draw).
    pub atlas: bool,
}

impl Player {
    /// What this player plays.
    #[must_use]
    pub fn plays(self) -> Plays {
        const BONES_OR_VERTICES: &[TextureKind] = &[TextureKind::SkinTrs, TextureKind::Vertex];
        const IMAGES: &[Format] = &[Format::Exr, Format::Png16];
        match self {
            Player::Three => Plays { textures: BONES_OR_VERTICES, formats: IMAGES, atlas: true },
            Player::View => Plays { textures: BONES_OR_VERTICES, formats: IMAGES, atlas: false },
            Player::Babylon => Plays { textures: &[TextureKind::Skin], formats: &[Format::Babylon], atlas: false },
        }
    }

    /// Every reason this player cannot play a bake of `texture` in `format`: none when it can.
    #[must_use]
    pub fn refusals(self, texture: TextureKind, format: Format) -> Vec<Unplayable> {
        let plays = self.plays();
        let mut refusals = Vec::new();
        if !plays.textures.contains(&texture) {
            refusals.push(Unplayable::Texture { player: self, texture });
        }
        if !plays.formats.contains(&format) {
            refusals.push(Unplayable::Format { player: self, format });
        }
        refusals
    }
}

/// One reason a player cannot play a bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Unplayable {
    /// A texture kind it does not play.
    #[error("{player} plays {} textures, not {texture}", one_of(player.plays().textures))]
    Texture {
        /// The player.
        player: Player,
        /// The bake's texture kind.
        texture: TextureKind,
    },
    /// A file format it does not read.
    #[error("{player} reads {} files, not {format}", one_of(player.plays().formats))]
    Format {
        /// The player.
        player: Player,
        /// The bake's format.
        format: Format,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_player_plays_its_first_texture_and_format_and_refuses_others_naming_each() {
        for player in [Player::Three, Player::Babylon, Player::View] {
            let plays = player.plays();
            assert!(player.refusals(plays.textures[0], plays.formats[0]).is_empty(), "{player}");
        }
        assert_eq!(
            Player::View.refusals(TextureKind::Local, Format::Npy),
            [
                Unplayable::Texture { player: Player::View, texture: TextureKind::Local },
                Unplayable::Format { player: Player::View, format: Format::Npy }
            ]
        );
        let words: Vec<String> =
            Player::View.refusals(TextureKind::Local, Format::Npy).iter().map(ToString::to_string).collect();
        assert_eq!(
            words,
            ["view plays skin-trs or vertex textures, not local", "view reads exr or png16 files, not npy"]
        );
    }
}
