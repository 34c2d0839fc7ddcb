/* The plant's magnetics at a point (plant.h): flux linkages and torque, for tests and tools. */
#include "plant_mag.h"

void plant_flux(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad, plant_mag_t *m)
{
    mag_eval(p, p->mag_general ? 1 : 0, i_d_a, i_q_a, cos(theta_e_rad), sin(theta_e_rad), m);
}

double plant_torque(const plant_t *p, double i_d_a, double i_q_a, double theta_e_rad)
{
    plant_mag_t m;
    plant_flux(p, i_d_a, i_q_a, theta_e_rad, &m);
    return torque_of(p, i_d_a, i_q_a, &m) + cog_torque(p, cos(theta_e_rad), sin(theta_e_rad));
}
