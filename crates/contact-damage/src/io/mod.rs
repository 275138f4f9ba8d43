//! Files in and out: Gmsh meshes, ParaView output, and the atomic writer behind every output file.

pub mod atomic;
pub mod gmsh;
pub mod vtk;
