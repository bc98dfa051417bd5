//! The finite-element plate simulator (8-node hexahedra), one more source of decays.
