/* thesis table 7.2 (figure 2): a blue glass sphere lit by a red light.
   Colours in 0-255 as printed in the thesis (any colour value above 1
   makes the whole file 0-255). */

V 200 200        /* viewport size in pixels: width height */
C 0 0 10         /* camera position */
A -2 2 1         /* target point the camera looks at */
U 0 1 0          /* camera up vector */
B 30 30          /* camera opening angles in degrees: horizontal vertical */

L 1              /* number of lights */
C 100 0 0        /* light colour r g b */
P -12 12 2       /* light position */
I 1              /* brightness */

O 2              /* number of objects */

/* sphere 1: glass lens */
T 0              /* object type: 0 sphere */
C -4.5 4.5 1.5   /* sphere centre */
R 1              /* sphere radius */
S                /* surface definition follows */
#C 10 0 100      /* surface colour r g b */
#A 0.03          /* ka  ambient coefficient */
#D 0.02          /* kd  diffuse coefficient */
#S 0.35          /* ks  specular (and global reflection) coefficient */
#T 0.6           /* kt  transmission coefficient (0 = opaque) */
#E 80            /* Phong exponent */
#N 1.5           /* index of refraction */

/* sphere 2: blue opaque, mirror-like sphere */
T 0
C 0 0 0
R 2
S
#C 0 0 100
#A 0.2
#D 0
#S 0.8
#T 0
#E 70
#N 1.0
