/* main.c: main() of the render program, which is render_main (app.h; render_main.c says what
 * it does). render-mpi has its own main (render/mpi/render_mpi.c), which calls render_main too.
 */
#include "app/app.h"

int main(int argc, char **argv) {
    return render_main(argc, argv, NULL);
}
