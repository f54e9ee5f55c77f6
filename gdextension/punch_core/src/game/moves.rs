//! A boxer's six punches, the two stances, and which hand throws what.
//!
//! Boxing numbers the punches 1 jab (lead straight), 2 cross (rear straight), 3 lead hook, 4 rear hook, 5 lead
//! uppercut, 6 rear uppercut; an orthodox fighter leads with the left hand, a southpaw with the right. Every
//! policy punches with the character's right hand; the left hand's punch is the same policy in the mirrored
//! world (`contract::mirror`), so each move is trained once and thrown with either hand.

use std::fmt;

pub use crate::contract::stance::Stance;

/// A hand (the right by default: the hand every policy punches with).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Hand {
    Left,
    #[default]
    Right,
}

impl Hand {
    /// "left" or "right", as signals and metrics carry it.
    pub fn name(self) -> &'static str {
        match self {
            Hand::Left => "left",
            Hand::Right => "right",
        }
    }

    /// Whether a policy (which punches with the right hand) plays this hand in the mirrored world.
    pub fn is_mirrored(self) -> bool {
        self == Hand::Left
    }
}

/// Which hand of a stance throws a move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Lead,
    Rear,
}

impl Stance {
    /// The hand on `side` in this stance.
    pub fn hand(self, side: Side) -> Hand {
        match (self, side) {
            (Stance::Orthodox, Side::Lead) | (Stance::Southpaw, Side::Rear) => Hand::Left,
            (Stance::Orthodox, Side::Rear) | (Stance::Southpaw, Side::Lead) => Hand::Right,
        }
    }
}

/// The six punches of boxing, in their numbers' order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Move {
    Jab,
    Cross,
    LeadHook,
    RearHook,
    LeadUppercut,
    RearUppercut,
}

/// A move name that is none of the six.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("no move named '{name}' (the moves: {})", Move::ALL.map(Move::name).join(", "))]
pub struct UnknownMove {
    pub name: String,
}

impl Move {
    /// Every move, by its boxing number (1 to 6).
    pub const ALL: [Move; 6] =
        [Move::Jab, Move::Cross, Move::LeadHook, Move::RearHook, Move::LeadUppercut, Move::RearUppercut];

    /// The name games use (`punch(&"lead_hook")`).
    pub fn name(self) -> &'static str {
        match self {
            Move::Jab => "jab",
            Move::Cross => "cross",
            Move::LeadHook => "lead_hook",
            Move::RearHook => "rear_hook",
            Move::LeadUppercut => "lead_uppercut",
            Move::RearUppercut => "rear_uppercut",
        }
    }

    /// The move of that name.
    pub fn from_name(name: &str) -> Result<Move, UnknownMove> {
        Move::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| UnknownMove { name: name.to_owned() })
    }

    /// Its number in boxing (1 jab to 6 rear uppercut).
    pub fn number(self) -> u8 {
        Move::ALL.iter().position(|&m| m == self).map_or(0, |index| index as u8 + 1)
    }

    /// Whether the lead or the rear hand throws it (odd numbers lead).
    pub fn side(self) -> Side {
        if self.number() % 2 == 1 { Side::Lead } else { Side::Rear }
    }

    /// The hand that throws it in `stance`.
    pub fn hand(self, stance: Stance) -> Hand {
        stance.hand(self.side())
    }
}

impl fmt::Display for Move {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_numbers_names_and_sides_are_boxings() {
        let names: Vec<_> = Move::ALL.iter().map(|m| (m.number(), m.name(), m.side())).collect();
        assert_eq!(
            names,
            [
                (1, "jab", Side::Lead),
                (2, "cross", Side::Rear),
                (3, "lead_hook", Side::Lead),
                (4, "rear_hook", Side::Rear),
                (5, "lead_uppercut", Side::Lead),
                (6, "rear_uppercut", Side::Rear)
            ]
        );
        for m in Move::ALL {
            assert_eq!(Move::from_name(m.name()), Ok(m));
            assert_eq!(m.to_string(), m.name());
        }
    }

    #[test]
    fn an_unknown_move_names_itself_and_the_six() {
        let error = Move::from_name("haymaker").expect_err("not a move");
        assert_eq!(
            error.to_string(),
            "no move named 'haymaker' (the moves: jab, cross, lead_hook, rear_hook, lead_uppercut, rear_uppercut)"
        );
        assert!(Move::from_name("").is_err() && Move::from_name("Jab").is_err());
    }

    #[test]
    fn orthodox_leads_with_the_left_and_southpaw_is_its_mirror() {
        assert_eq!(Move::Jab.hand(Stance::Orthodox), Hand::Left);
        assert_eq!(Move::Cross.hand(Stance::Orthodox), Hand::Right);
        assert_eq!(Stance::default(), Stance::Orthodox);
        for m in Move::ALL {
            assert_ne!(m.hand(Stance::Orthodox), m.hand(Stance::Southpaw), "{m}: the other stance, the other hand");
        }
        assert!(Hand::Left.is_mirrored() && !Hand::Right.is_mirrored());
        assert_eq!((Hand::Left.name(), Hand::Right.name()), ("left", "right"));
    }
}
