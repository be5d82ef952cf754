/* Registration subcommands (apps/cmd_register.c, apps/cmd_repose.c). Entry points for the
 * command table in apps/main.c:
 *   {"register", "register the body model to a 3-D scan (Ceres)", spx_cmd_register},
 *   {"repose",   "pose a registered person with a BVH frame", spx_cmd_repose},
 *   {"reshape",  "change a registered person's shape coefficients", spx_cmd_reshape}, */
#ifndef SPX_APPS_CMD_FIT_H
#define SPX_APPS_CMD_FIT_H

int spx_cmd_register(int argc, char **argv);
int spx_cmd_repose(int argc, char **argv);
int spx_cmd_reshape(int argc, char **argv);
int spx_cmd_bake(int argc, char **argv); /* apps/cmd_bake.c */

#endif
