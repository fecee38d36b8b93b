#pragma once
/// @file stages.hpp
/// Every stage of the pipeline as a function of its own, so each can be tested against
/// a brute-force reference; FramePipeline chains them. One header per step of the paper
/// (Genesio et al., Table II), and the departures from it.

#include "mobmap/perception/reduction.hpp"     // 1. voxel grid
#include "mobmap/perception/denoising.hpp"     // 2. statistical outlier removal
#include "mobmap/perception/normals.hpp"       // 3. PCA normals
#include "mobmap/perception/rgbn.hpp"          // 4. RGB-N colours
#include "mobmap/perception/ground.hpp"        // 5. RANSAC ground
#include "mobmap/perception/segmentation.hpp"  // 6. colour region growing
#include "mobmap/perception/departures.hpp"    //    refinements the paper does not have
#include "mobmap/perception/roughness.hpp"     // 7. Delaunay roughness
