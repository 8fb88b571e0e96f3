//! The thesis' legacy input decks (YOUNG) → descriptions.
