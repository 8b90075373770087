#include "sphnl/parallel/gather_particles.hpp"

#include <algorithm>
#include <numeric>

namespace sphnl {

ParticleSet gather_particles(Communicator& comm, const ParticleSet& ps, std::size_t owned) {
  constexpr std::size_t kFields = 11;
  std::vector<double> mine;
  mine.reserve(owned * kFields);
  for (std::size_t i = 0; i < owned; ++i)
    mine.insert(mine.end(), {static_cast<double>(ps.id[i]), ps.x[i], ps.y[i], ps.z[i], ps.vx[i], ps.vy[i], ps.vz[i],
                             ps.rho[i], ps.pressure[i], ps.mass[i], static_cast<double>(ps.type[i])});
  std::vector<std::vector<double>> all;
  comm.gather(mine, all);
  ParticleSet out;
  std::size_t n = 0;
  for (const auto& r : all) n += r.size() / kFields;
  out.resize(n);
  // Records sorted by id: memory order is id order, as in a fresh case.
  std::vector<const double*> records;
  records.reserve(n);
  for (const auto& r : all)
    for (std::size_t k = 0; k < r.size(); k += kFields) records.push_back(r.data() + k);
  std::sort(records.begin(), records.end(), [](const double* a, const double* b) { return a[0] < b[0]; });
  for (std::size_t i = 0; i < n; ++i) {
    const double* r = records[i];
    out.id[i] = static_cast<std::uint32_t>(r[0]);
    out.x[i] = r[1]; out.y[i] = r[2]; out.z[i] = r[3];
    out.vx[i] = r[4]; out.vy[i] = r[5]; out.vz[i] = r[6];
    out.rho[i] = r[7]; out.pressure[i] = r[8]; out.mass[i] = r[9];
    out.type[i] = static_cast<ParticleType>(static_cast<int>(r[10]));
  }
  return out;
}

}  // namespace sphnl
