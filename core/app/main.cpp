#include <cstdio>
#include "sphnl/simulation.hpp"
int main() {
  sphnl::RunConfig c;
  c.steps = 20;
  sphnl::Simulation sim(c);
  std::printf("N=%zu fluid=%zu dx=%g h=%g\n", sim.particles().size(), sim.case_info().n_fluid, sim.case_info().dx, sim.case_info().h);
  for (int s = 0; s < 20; ++s) sim.step();
  auto& t = sim.phase_times();
  std::printf("t=%g dt=%g nl=%g force=%g upd=%g  per particle-step %.3g us, inter/particle %.1f cand/particle %.1f\n", sim.time(), sim.last_dt(),
    t.neighbour_list, t.force, t.update, t.total()/20/sim.particles().size()*1e6,
    2.0*sim.neighbour_stats().interactions/20/sim.particles().size(), 2.0*sim.neighbour_stats().candidates/20/sim.particles().size());
}
