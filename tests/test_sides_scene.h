/* test_sides_scene.h: the scene of the side-rule tests (test_render_sides.c and
 * test_render_sides_fit.c): a floor -2..2 x -2..2, a tall wall at x = 0 (1 high) and a low
 * wall at y = 0.5, all white Lambertian. */
#ifndef TEST_SIDES_SCENE_H
#define TEST_SIDES_SCENE_H

#define SIDES_SCENE                                                                                          \
    "{\"camera\": {\"eye\": [0, -5, 3], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8}," \
    " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"                              \
    " \"objects\": ["                                                                                        \
    "  {\"type\": \"quad\", \"vertices\": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], \"material\": \"white\"}," \
    "  {\"type\": \"quad\", \"vertices\": [[0, -2, 0], [0, 2, 0], [0, 2, 1], [0, -2, 1]], \"material\": \"white\"}," \
    "  {\"type\": \"quad\", \"vertices\": [[-2, 0.5, 0], [2, 0.5, 0], [2, 0.5, 0.02], [-2, 0.5, 0.02]], \"material\": \"white\"}]}"

#endif
