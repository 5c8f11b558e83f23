#pragma once
// JSON fragments shared by the verbs that report a reconstruction (sweep, reconstruct).
#include <nlohmann/json.hpp>

#include "topo/analysis.h"

namespace topocal::tools {

nlohmann::json SurfaceFitJson(const topo::BiconicFit& fit);
nlohmann::json ReconstructionJson(const topo::Reconstruction& r);
// "pv_tangential_D", "pv_axial_D", map and covered radius; "pv_um", "rms_um" when the truth was known.
nlohmann::json ErrorsJson(const topo::Analysis& a);
nlohmann::json PolynomialJson(const topo::TaylorPolynomial& p);

}  // namespace topocal::tools
