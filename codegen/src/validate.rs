//! Description → model: every rule of the contract's Validation section, with places.
