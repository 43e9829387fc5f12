//! The driving scenario: a three-lane road with obstacles and a lidar.
//!
//! Status: this crate is a placeholder of the workspace. The environment comes
//! with the issue "The driving scenario"; until then it provides nothing.
